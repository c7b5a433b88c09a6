"""When a run stops: blow-ups of the positions, growth of the energy ledger, the stability pre-check.

No clamps hide an instability (the README's rule). Three checks, each with a scale fixed
from the scene's initial state when the session starts, so a run stepped in any chunks
stops at the same step with the same message:

* **positions**: a non-finite state, or a position beyond ``blowup * (1 + max |x0|)``
  (checked after every step, by the stepping loops themselves);
* **ledger growth** (:class:`LedgerCheck`): the ledger total ``E = K + U + D - W_ext`` is
  constant for the exact motion; an instability whose amplitude saturates (stiff springs
  swinging through zero length, a contact bouncing) keeps the positions bounded but makes
  ``E`` grow. The check reads ``E`` every :attr:`LedgerCheck.every` steps;
* **the pre-check** (:func:`check_stability`): an explicit method's predicted stable dt,
  quoted in every message.
"""

from __future__ import annotations

import math
import warnings
from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from mslab.errors import StabilityWarning

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator
    from mslab.scenes.builder import Scene

#: force evaluations between two ledger checks: a check (K and U in numpy, about one numpy
#: force evaluation) then costs a few per cent of the compiled steps between checks
CHECK_EVALS = 128
#: growth that counts as an instability: the ledger gained more than the scene's energy scale
#: (``LEVEL``) and more than ``GROWTH`` times its largest deviation in the first quarter so far
LEVEL = 1.0
GROWTH = 100.0


def position_limit(scene: Scene, blowup: float) -> float:
    """Return the largest |position| a run may reach: ``blowup * (1 + max |x0|)``."""
    return blowup * (1.0 + float(np.max(np.abs(scene.state0.x))))


def hint(stable_dt: float | None) -> str:
    """Return the end of a blow-up message: the predicted stable dt, or what to try."""
    if stable_dt is None:
        return "; try a smaller dt or an implicit method"
    if stable_dt == 0:
        return "; no dt is stable for this method on this scene: try an implicit or symplectic method"
    return f"; predicted stable dt = {stable_dt:.4g}"


def check_stability(scene: Scene, integrator: Integrator, dt: float, stable_dt: float | None,
                    stacklevel: int) -> float | None:
    """Return the predicted stable dt (or the given one); warn when dt exceeds it. Counts no work."""
    from mslab.stability import predicted_stable_dt
    from mslab.threads import single_threaded_blas

    predicted = single_threaded_blas(predicted_stable_dt)(scene, integrator)
    if predicted is not None and dt > predicted:
        what = (f"{integrator.name} has no stable dt on this scene: its undamped oscillations grow "
                f"at every dt (slowly when dt is small)"
                if predicted == 0 else f"dt = {dt:g} exceeds the predicted stable dt = {predicted:.4g} "
                f"of {integrator.name} ({dt / predicted:.3g} x)")
        warnings.warn(f"{what}; the run may blow up", StabilityWarning, stacklevel=stacklevel)
    return predicted if stable_dt is None else stable_dt


class LedgerCheck:
    """The saturation detector: growth of the ledger total ``E = K + U + D - W_ext``.

    At every checked step ``s`` (multiples of :attr:`every`, and the declared end of a run)
    the deviation ``g(s) = (E(s) - E(0)) / scale`` is compared with what came before. A
    run is unstable at ``s`` when ``g(s)`` is NaN or above ``energy_blowup`` (default 1e4),
    or when it **grew**: ``g(s) > LEVEL`` (the ledger gained the scene's whole energy scale,
    which no method of the right order does at a stable dt) and ``g(s) > GROWTH * r(s)``,
    where ``r(s)`` is the largest ``|g|`` at the checks up to ``s / 4``. A stable method's
    error reaches its size early and stays (symplectic) or drifts slowly; an instability
    grows geometrically, saturated or not. Only gains count: implicit methods lose energy.

    ``scale`` is :func:`mslab.ledger.initial_energy_scale`; a scene that starts at rest with
    nothing to release (scale 0: a wind drives it) uses the largest kinetic energy at the
    checks up to ``s / 4``. ``energy_blowup = inf`` turns the check off.
    """

    def __init__(self, scale: float, energy_blowup: float, n_stages: int, end: int | None):
        self.scale, self.energy_blowup, self.end = scale, energy_blowup, end
        self.on = not math.isinf(energy_blowup)
        #: steps between two checks
        self.every = max(1, CHECK_EVALS // max(1, n_stages))
        self._e0 = 0.0
        self._pending: deque = deque()  # (step, E - E0, K) of checks not yet in the first quarter
        self._early = (0, 0.0, 0.0)  # last step, largest |E - E0|, largest K of the first quarter

    def due(self, step: int) -> bool:
        """Return whether the ledger is checked after ``step``."""
        return self.on and (step % self.every == 0 or step == self.end)

    def next_due(self, step: int) -> int:
        """Return the first checked step after ``step`` (a large number when the check is off)."""
        if not self.on:
            return 2**62
        nxt = (step // self.every + 1) * self.every
        return min(nxt, self.end) if self.end is not None and self.end > step else nxt

    def start(self, total: float) -> None:
        """Record ``E(0)``."""
        self._e0 = total
        self._pending = deque([(0, 0.0, 0.0)])
        self._early = (0, 0.0, 0.0)

    def check(self, step: int, total: float, kinetic: float) -> str | None:
        """Record ``E(step)``; return why the run is unstable there, or None."""
        since, deviation, k_max = self._early
        while self._pending and self._pending[0][0] <= step // 4:  # the first quarter grows
            s, d, k = self._pending.popleft()
            since, deviation, k_max = s, max(deviation, abs(d)), max(k_max, k)
        self._early = (since, deviation, k_max)
        change = total - self._e0
        self._pending.append((step, change, kinetic))
        scale = self.scale if self.scale > 0 else k_max
        if not scale > 0:
            return None
        growth, reference = change / scale, deviation / scale
        if not growth <= self.energy_blowup:  # NaN counts as over
            return f"grew by {growth:.3g} x the scene's energy scale"
        if growth > LEVEL and growth > GROWTH * reference:
            return (f"grew by {growth:.3g} x the scene's energy scale, "
                    + (f"{growth / reference:.3g} x its largest deviation up to step {since} "
                       if reference > 0 else f"from exactly its initial value at step {since} ")
                    + "(a growth only an instability makes: the positions stayed bounded, so its "
                      "amplitude saturated, e.g. springs swinging through zero length or a contact "
                      "bouncing)")
        return None
