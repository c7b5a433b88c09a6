"""The cheap checks ``mslab run`` makes before it starts: the animation tool and the predicted stable dt."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator
    from mslab.scenes.builder import Scene

#: above this many unknowns (n_particles * dim) the stable-dt prediction is skipped, as in simulate
MAX_DOFS = 5000


def animation_problem(kind: str | None) -> str | None:
    """Why ``--animate kind`` cannot be written on this machine (None: it can)."""
    if kind is None:
        return None
    if kind == "gif":
        try:
            import PIL  # noqa: F401
        except ImportError:
            return "GIF animations need Pillow, which does not import (pip install pillow)"
        return None
    from matplotlib import animation as mpl_animation

    if not mpl_animation.writers.is_available("ffmpeg"):
        return "ffmpeg not found; install it or use --animate gif"
    return None


def a_stable(method: Integrator) -> bool:
    """Tell whether no step limit applies: A-stable coefficients and not a fixed-point iteration.

    A-stable: ``|R(z)| <= 1`` on the whole negative real axis and the imaginary axis and
    bounded oscillations at every ``dt w`` (:mod:`mslab.stability`, from the coefficients;
    cheap). A fixed-point solver only converges below a step limit, so it never counts.
    """
    from mslab import stability

    if method.explicit or getattr(method, "solver", None) == "fixed_point" or method.name.endswith("_fp"):
        return False
    return (stability.real_interval(method) == -math.inf and stability.imag_limit(method) == math.inf
            and stability.oscillator_limit(method) == math.inf)


def predicted_dt(scene: Scene, method: str) -> tuple[float | None, str | None]:
    """Return the predicted largest stable step (None: not computed) and a note when it was skipped.

    Skipped for A-stable methods (inf, no analysis needed) and above :data:`MAX_DOFS`
    unknowns (the eigenvalue analysis would take longer than many runs). On a terminal a
    progress line appears if the analysis takes more than about 2 s.
    """
    from mslab.integrators.base import get_method
    from mslab.progress import Progress
    from mslab.stability import predicted_stable_dt

    m = get_method(method)
    if a_stable(m):
        return math.inf, None
    dofs = scene.n_particles * scene.dim
    if dofs > MAX_DOFS:
        return None, (f"stable-dt prediction skipped: {dofs} unknowns, more than {MAX_DOFS} (as in "
                      f"simulate); a blow-up still stops the run")
    with Progress(None, f"predicting the stable dt of {m.name} (eigenvalues)"):
        return predicted_stable_dt(scene, m, max_dofs=MAX_DOFS), None


def prediction_line(method: str, dt: float, predicted: float | None) -> str:
    """``predicted stable dt for rk4: 0.02828 s (dt = 0.01 is below it)`` and the like."""
    head = f"predicted stable dt for {method}:"
    if predicted is None or math.isnan(predicted):
        return f"{head} not available (the eigenvalue analysis failed); a blow-up still stops the run"
    if predicted == math.inf:
        return f"{head} no limit ({method} is A-stable; eigenvalue analysis skipped)"
    if predicted == 0:
        return (f"{head} none: on this scene's undamped oscillations |R| > 1 at every dt, so they "
                f"grow (slowly when dt is small: a short run may look bounded)")
    side = "above" if dt > predicted else "below"
    return f"{head} {predicted:.4g} s (dt = {dt:g} is {side} it)"
