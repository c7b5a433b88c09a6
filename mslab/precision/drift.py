"""Energy drift: the relative error of the ledger K + U + D over a long run, and a verdict."""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from mslab.errors import ConvergenceError, InstabilityError, StabilityWarning
from mslab.fast.job import job_backends
from mslab.integrators.base import get_method
from mslab.precision.runs import _method_names, _progress_bar, _save_every
from mslab.scenes.builder import Scene
from mslab.simulate import step_count

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator

#: energy-drift verdict (see :func:`drift_verdict`)
DRIFT_TREND = 3.0
DRIFT_GROWTH = 10.0
DRIFT_FLOOR = 1e-11


@dataclass
class Drift:
    """Energy behaviour of one method over a long run.

    Attributes
    ----------
    method : str
    t : ndarray, shape (n_saved,)
    error : ndarray, shape (n_saved,)
        Relative error of the ledger total ``(E(t) - E(0)) / scale``
        (:meth:`mslab.simulate.Energy.relative_drift`).
    drift_rate : float
        Slope [1/s] of the least-squares line through ``error(t)`` over the second half
        of the run (after the start-up transient).
    trend : float
        ``|drift_rate| * (duration of the second half) / std(error - line)``: how far the
        line moves compared with the scatter about it.
    early, late : float
        Peak ``|error|`` over the first and the last quarter of the run.
    verdict : str
        ``"bounded"`` or ``"drifting"`` (rule in :func:`drift_verdict`).
    steps, n_force : int
    wall_time : float
    complete : bool
        False when the run stopped early (its saved part is kept).
    failure : str or None
        The error message of a run that stopped early.
    stopped : str or None
        Why it stopped: ``"blew up"`` (an :class:`~mslab.errors.InstabilityError`; verdict
        "drifting") or ``"no convergence"`` (a :class:`~mslab.errors.ConvergenceError` of
        an implicit method's iteration; verdict "no convergence": it says nothing about
        energy). ``steps`` then counts the steps up to and including the failing one.
    """

    method: str
    t: np.ndarray
    error: np.ndarray
    drift_rate: float
    trend: float
    early: float
    late: float
    verdict: str
    steps: int
    n_force: int
    wall_time: float
    complete: bool = True
    failure: str | None = None
    stopped: str | None = None

    @property
    def max_error(self) -> float:
        """Largest absolute relative energy error of the run (nan when there are no samples)."""
        return float(np.max(np.abs(self.error))) if self.error.size else math.nan

    def as_record(self) -> dict:
        """Flat summary without the arrays (for tables and JSON)."""
        return {"method": self.method, "steps": self.steps, "n_force": self.n_force,
                "wall_time": self.wall_time, "max_error": self.max_error,
                "final_error": float(self.error[-1]) if self.error.size else math.nan,
                "drift_rate": self.drift_rate, "trend": self.trend, "early": self.early,
                "late": self.late, "verdict": self.verdict, "complete": self.complete,
                "failure": self.failure, "stopped": self.stopped}


def drift_verdict(t: np.ndarray, error: np.ndarray, *, trend_limit: float = DRIFT_TREND,
                  growth_limit: float = DRIFT_GROWTH, floor: float = DRIFT_FLOOR) -> dict:
    """Bounded or drifting: the rule applied to a relative energy error ``error(t)``.

    A symplectic method's energy error oscillates about a fixed level for very long
    times; a non-symplectic one moves away, linearly (RK4, implicit Euler: energy lost)
    or exponentially (forward Euler: energy gained). The rule, on the run's samples:

    1. **trend** -- fit a line to the error over the second half of the run (the first
       half may hold a start-up transient). Drifting when the line moves by more than
       ``trend_limit = 3`` times the standard deviation of the error about the line:
       a bounded oscillation gives a trend near 0 (measured below 0.5 on the chain), a
       steady drift one of 10 or more.
    2. **growth** -- drifting when the peak ``|error|`` of the last quarter exceeds
       ``growth_limit = 10`` times the peak of the first quarter (exponential growth,
       which a straight line fits badly).
    3. **floor** -- errors whose peak stays below ``floor = 1e-11`` are round-off:
       bounded.

    Parameters
    ----------
    t, error : array_like, shape (n,)

    Returns
    -------
    dict
        ``verdict``, ``drift_rate`` (slope of the second-half line, 1/s), ``trend``,
        ``early``, ``late`` (peak ``|error|`` of the first and last quarter).
    """
    t = np.asarray(t, dtype=float)
    e = np.asarray(error, dtype=float)
    out = {"verdict": "bounded", "drift_rate": math.nan, "trend": math.nan, "early": math.nan,
           "late": math.nan}
    if t.size < 8 or not np.all(np.isfinite(e)):
        return out
    span = t[-1] - t[0]
    out["early"] = early = float(np.max(np.abs(e[t <= t[0] + 0.25 * span])))
    out["late"] = late = float(np.max(np.abs(e[t >= t[-1] - 0.25 * span])))
    half = t >= t[0] + 0.5 * span
    slope, intercept = np.polyfit(t[half], e[half], 1)
    scatter = float(np.std(e[half] - (intercept + slope * t[half])))
    moved = abs(slope) * (t[-1] - t[half][0])
    out["drift_rate"] = float(slope)
    out["trend"] = moved / scatter if scatter > 0 else (math.inf if moved > 0 else 0.0)
    if max(early, late) <= floor:
        return out
    if out["trend"] > trend_limit or late > growth_limit * early:
        out["verdict"] = "drifting"
    return out


class DriftInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`energy_drift`: ``.finished`` holds the methods already done."""

    def __init__(self, finished: dict):
        super().__init__("interrupted")
        self.finished = finished


def energy_drift(scene: Scene, methods: Sequence[str | Integrator], dt: float | None = None,
                 t_end: float | None = None, *, n_save: int = 2000,
                 trend_limit: float = DRIFT_TREND, growth_limit: float = DRIFT_GROWTH,
                 warm_up: bool = True, progress: bool | None = False, backend: str | None = None) -> dict:
    """Relative energy error over time, drift rate and verdict of each method.

    Parameters
    ----------
    scene : Scene
        Best an undamped one (e.g. ``chain(gravity=9.81)`` without damping): the ledger
        total ``K + U + D`` is then constant for the exact solution and any change is the
        method's.
    methods : sequence of str
    dt, t_end : float, optional
        Defaults from ``scene.settings``.
    n_save : int
        About this many saved times.
    trend_limit, growth_limit : float
        Thresholds of the verdict (see :func:`drift_verdict`).
    warm_up : bool
        Run 10 steps of each method first, so that one-time costs (compiling, caches)
        stay out of the reported wall time.
    progress : bool, None or object with ``update(n)``
        Progress by the clock over all the methods' steps, naming the current method
        (:mod:`mslab.progress`); None: on a terminal, False: none, an object: the caller's.
    backend : {"auto", "numba", "numpy"}, optional
        None: ``$MSLAB_BACKEND`` or ``"auto"``, decided once for all the methods' runs
        (:func:`mslab.fast.job.job_backends`).

    Returns
    -------
    dict
        ``{method: Drift}`` in the order given. A run that blows up keeps what it saved,
        gets ``complete = False`` and the verdict "drifting"; one whose implicit iteration
        fails gets the verdict "no convergence".
    """
    dt = float(scene.settings.dt if dt is None else dt)
    t_end = float(scene.settings.t_end if t_end is None else t_end)
    steps = step_count(t_end, dt)
    names = _method_names(methods)
    backends = dict(zip(names, job_backends(scene.system, [(get_method(m), steps) for m in names], backend),
                        strict=True))
    bar, owned = _progress_bar(len(names) * steps, progress, f"energy drift {scene.name}", unit="step")
    out = {}
    try:
        for i, m in enumerate(names):
            if not _drift_of(scene, m, i, names, dt, t_end, steps, backends[m], bar, warm_up, n_save,
                             trend_limit, growth_limit, out):
                raise DriftInterrupted(out)
    finally:
        if owned:
            bar.close()
    return out


def _drift_of(scene: Scene, m: str, i: int, names: list[str], dt: float, t_end: float, steps: int,
              backend: str, bar: object, warm_up: bool, n_save: int, trend_limit: float,
              growth_limit: float, out: dict) -> bool:
    """Run method ``m`` into ``out[m]``; False on Ctrl-C (``out`` keeps the methods finished before)."""
    from mslab.simulate import simulate

    failure = kind = None
    if hasattr(bar, "describe"):  # the current method, on the bar
        bar.describe(f"{m} ({i + 1}/{len(names)})")
    done = getattr(bar, "n", 0)
    try:
        with warnings.catch_warnings():  # the verdict says it
            warnings.simplefilter("ignore", StabilityWarning)
            if warm_up and steps > 20:  # compiled kernels, caches: out of the wall time
                try:
                    simulate(scene, m, dt, 10 * dt, progress=False, backend=backend)
                except InstabilityError:
                    pass
            traj = simulate(scene, m, dt, t_end, save_every=_save_every(steps, n_save),
                            progress=bar if bar is not None else False, backend=backend)
    except KeyboardInterrupt:
        return False
    except ConvergenceError as err:  # not an energy behaviour: the iteration failed
        traj, failure, kind = err.trajectory, str(err), "no convergence"
    except InstabilityError as err:
        traj, failure, kind = err.trajectory, str(err), "blew up"
    error = traj.energy.relative_drift() if traj.t.size else np.zeros(0)
    rule = drift_verdict(traj.t, error, trend_limit=trend_limit, growth_limit=growth_limit)
    verdict = {None: rule["verdict"], "blew up": "drifting"}.get(kind, kind)
    out[m] = Drift(m, traj.t, error, rule["drift_rate"], rule["trend"], rule["early"], rule["late"],
                   verdict, traj.stats.steps, traj.stats.n_force, traj.stats.wall_time,
                   failure is None, failure, kind)
    if bar is not None and hasattr(bar, "n"):
        bar.update(done + steps - bar.n)  # a run that stopped early: skip its remaining steps
    return True
