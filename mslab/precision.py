"""Accuracy versus cost: convergence orders, work-precision records and energy drift.

Three experiments answer "what does accuracy cost?" for any scene and any method:

* :func:`convergence` -- the error at ``t_end`` for a sweep of steps ``dt`` and the
  observed order ``p`` (least-squares slope of ``log error`` against ``log dt``); a
  method of order ``p`` has global error ``O(dt^p)`` (local error ``O(dt^(p+1))``).
* :func:`work_precision` -- one flat record per (method, dt): error, counted work
  (force evaluations, Jacobians, linear solves) and wall time; with scipy's
  ``solve_ivp`` (RK45, DOP853, Radau, BDF) over a tolerance sweep on the same forces
  as reference curves (:func:`scipy_records`).
* :func:`energy_drift` -- the relative error of the energy ledger ``K + U + D`` over a
  long run, its drift rate and a bounded-versus-drifting verdict.

Decisions
---------
**Error.** ``error`` is the max-norm of the final-state error over positions and
velocities, ``max(max|x - x_ref|, max|v - v_ref|)`` at ``t_end``; ``error_rms`` is the
root mean square of the same differences over every saved time (about ``n_save`` of
them, always including ``t_end``).

**Reference.** The scene's closed form ``scene.exact(t)`` where it has one (the
oscillators); otherwise scipy's ``solve_ivp(DOP853)`` with ``rtol = atol = 1e-12`` on the
first-order system ``y = (x, v)``, ``y' = (v, a(x, v))`` built from the very same
``scene.system.acceleration`` (pinned particles have zero acceleration and stay put).
The reference is cached per scene object and ``t_end``.

**Timing** follows DiffEqDevTools: a run that computes the error and warms up (imports,
compiled kernels, caches), then timed runs that compute nothing else, repeated until
``repeats`` runs or a ``budget`` of seconds is used (at least one); the record keeps the
minimum. When the error runs happened in worker processes (``jobs > 1``), the calling
process first makes one untimed warm-up run per method. mslab runs are timed by
``simulate``'s own ``stats.wall_time`` (stepping only), scipy runs around ``solve_ivp``.

**Parallel sweeps** (``jobs > 1``) run only the error runs in a process pool (their
results, counts included, do not depend on the machine's load). The timing runs always
run one after the other in the calling process, so no timing shares the machine with
another run of the sweep.

**Failures.** A (method, dt) that blows up (:class:`~mslab.errors.InstabilityError`) or
whose implicit iteration fails (:class:`~mslab.errors.ConvergenceError`) gives a record
with ``ok = False``, ``error = error_rms = inf``, ``wall_time = nan`` and the message in
``failure``; the sweep goes on.
"""

from __future__ import annotations

import math
import sys
import time
import warnings
import weakref
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from mslab.errors import InstabilityError, StabilityWarning
from mslab.integrators.base import get_method
from mslab.scenes.builder import Scene
from mslab.simulate import step_count

#: scipy's ``solve_ivp`` methods drawn as reference curves
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF")
#: default tolerance sweep of the scipy curves (``atol = rtol``)
SCIPY_RTOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
#: errors below this are round-off, not truncation error; left out of the order fit
ROUNDOFF_FLOOR = 1e-11
#: energy-drift verdict (see :func:`drift_verdict`)
DRIFT_TREND = 3.0
DRIFT_GROWTH = 10.0
DRIFT_FLOOR = 1e-11


# -- reference solutions ---------------------------------------------------------------------------------
@dataclass
class Reference:
    """The accurate solution errors are measured against.

    Attributes
    ----------
    t_end : float
    x_end, v_end : ndarray, shape (n_particles, dim)
        The reference state at ``t_end``.
    kind : str
        ``"exact"`` (closed form) or ``"DOP853"`` (scipy, rtol = atol = ``rtol``).
    n_force : int
        Force evaluations the scipy reference cost (0 for a closed form).
    """

    t_end: float
    x_end: np.ndarray
    v_end: np.ndarray
    kind: str
    n_force: int = 0
    _dense: object = field(default=None, repr=False)

    def at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Reference ``(x, v)`` at times ``t``, each of shape (n_t, n_particles, dim)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self._dense(t)


_REFERENCES: dict = {}


def _flat_rhs(system, shape):
    """``f(t, y)`` of the first-order system ``y = (x, v)`` for solve_ivp; counts n_force."""
    n = int(np.prod(shape))

    def f(t, y):
        a = system.acceleration(y[:n].reshape(shape), y[n:].reshape(shape))
        return np.concatenate([y[n:], a.ravel()])

    return f


def _flat_jacobian(system, shape):
    """``df/dy = [[0, I], [M^-1 K, M^-1 D]]`` (sparse) for scipy's implicit solvers; counts n_jac."""
    import scipy.sparse as sp

    n = int(np.prod(shape))
    minv = system.inv_mass_diag

    def jac(t, y):
        K, D = system.jacobians(y[:n].reshape(shape), y[n:].reshape(shape))
        lower_v = minv @ D if D is not None else sp.csr_matrix((n, n))
        return sp.bmat([[None, sp.identity(n)], [minv @ K, lower_v]], format="csc")

    return jac


def _y0(scene: Scene) -> np.ndarray:
    return np.concatenate([scene.state0.x.ravel(), scene.state0.v.ravel()])


def reference_solution(scene: Scene, t_end: float, *, use_exact: bool = True,
                       rtol: float = 1e-12, atol: float = 1e-12) -> Reference:
    """The reference solution of ``scene`` on ``[0, t_end]`` (cached per scene and t_end).

    Parameters
    ----------
    scene : Scene
    t_end : float
    use_exact : bool
        Use ``scene.exact`` when the scene has it; False forces the scipy reference
        (to check it against the closed form).
    rtol, atol : float
        Tolerances of ``solve_ivp(method="DOP853")``.

    Returns
    -------
    Reference
    """
    t_end = float(t_end)
    shape = scene.state0.x.shape
    if use_exact and scene.exact is not None:
        x_end, v_end = scene.exact(np.array([t_end]))
        return Reference(t_end, x_end[0], v_end[0], "exact", 0, scene.exact)
    key = (id(scene), scene.name, t_end, rtol, atol)
    hit = _REFERENCES.get(key)
    if hit is not None and hit[0]() is scene:
        return hit[1]
    from scipy.integrate import solve_ivp

    before = scene.system.counters.n_force
    sol = solve_ivp(_flat_rhs(scene.system, shape), (0.0, t_end), _y0(scene), method="DOP853",
                    rtol=rtol, atol=atol, dense_output=True)
    if not sol.success:
        raise InstabilityError(f"reference solution (DOP853) failed: {sol.message}")
    n = int(np.prod(shape))

    def dense(t):
        y = sol.sol(t).T  # (n_t, 2n)
        return y[:, :n].reshape((-1,) + shape), y[:, n:].reshape((-1,) + shape)

    ref = Reference(t_end, sol.y[:n, -1].reshape(shape), sol.y[n:, -1].reshape(shape), "DOP853",
                    scene.system.counters.n_force - before, dense)
    _REFERENCES[key] = (weakref.ref(scene), ref)
    return ref


# -- one run ---------------------------------------------------------------------------------------------
def _save_every(steps: int, n_save: int) -> int:
    return max(1, steps // max(1, n_save))


def _mslab_run(scene: Scene, method: str, dt: float, t_end: float, n_save: int) -> dict:
    """One error run of an mslab method: saved samples and counted work (picklable result)."""
    from mslab.simulate import simulate

    steps = step_count(t_end, dt)
    try:
        with warnings.catch_warnings():  # a predicted instability shows in the record itself
            warnings.simplefilter("ignore", StabilityWarning)
            traj = simulate(scene, method, dt, t_end, save_every=_save_every(steps, n_save), progress=False)
    except InstabilityError as err:  # ConvergenceError too
        stats = err.trajectory.stats.as_dict() if err.trajectory is not None else {}
        return {"ok": False, "failure": str(err), "stats": stats}
    return {"ok": True, "failure": None, "t": traj.t, "x": traj.x, "v": traj.v,
            "stats": traj.stats.as_dict()}


def _scipy_run(scene: Scene, solver: str, rtol: float, t_end: float, atol: float | None) -> dict:
    """One solve_ivp run on the scene's forces; saved samples are the solver's own steps.

    No ``t_eval`` and no dense output: DOP853's interpolant would cost extra force
    evaluations and inflate ``nfev``.
    """
    from scipy.integrate import solve_ivp

    shape = scene.state0.x.shape
    n = int(np.prod(shape))
    system = scene.system
    kwargs = {}
    if solver in ("Radau", "BDF", "LSODA"):
        kwargs["jac"] = _flat_jacobian(system, shape)
    start = time.perf_counter()
    sol = solve_ivp(_flat_rhs(system, shape), (0.0, t_end), _y0(scene), method=solver, rtol=rtol,
                    atol=rtol if atol is None else atol, **kwargs)
    wall = time.perf_counter() - start
    steps = max(len(sol.t) - 1, 0)
    stats = {"method": f"scipy:{solver}", "dt": t_end / max(steps, 1), "steps": steps,
             "n_force": int(sol.nfev), "n_jac": int(sol.njev), "n_solve": int(sol.nlu), "n_iter": 0,
             "wall_time": wall}
    if not sol.success or not np.all(np.isfinite(sol.y)):
        return {"ok": False, "failure": f"solve_ivp({solver}) failed: {sol.message}", "stats": stats}
    y = sol.y.T
    return {"ok": True, "failure": None, "t": sol.t, "x": y[:, :n].reshape((-1,) + shape),
            "v": y[:, n:].reshape((-1,) + shape), "stats": stats}


def _errors(run: dict, ref: Reference) -> tuple[float, float]:
    """(final-state max-norm error, RMS error over the saved times) of x and v."""
    if not run["ok"]:
        return math.inf, math.inf
    xr, vr = ref.at(run["t"])
    dx, dv = run["x"] - xr, run["v"] - vr
    final = max(float(np.max(np.abs(dx[-1]))), float(np.max(np.abs(dv[-1]))))
    rms = float(np.sqrt(0.5 * (np.mean(dx ** 2) + np.mean(dv ** 2))))
    return final, rms


def _record(solver: str, method: str, dt: float, rtol: float | None, run: dict, ref: Reference) -> dict:
    error, error_rms = _errors(run, ref)
    s = run["stats"]
    return {
        "solver": solver, "method": method, "dt": float(dt), "rtol": rtol,
        "error": error, "error_rms": error_rms,
        "n_force": int(s.get("n_force", 0)), "n_jac": int(s.get("n_jac", 0)),
        "n_solve": int(s.get("n_solve", 0)), "n_iter": int(s.get("n_iter", 0)),
        "steps": int(s.get("steps", 0)), "wall_time": math.nan,
        "ok": bool(run["ok"]), "failure": run["failure"], "reference": ref.kind,
    }


def _time_it(run_once, repeats: int, budget: float, warm_up: bool) -> float:
    """Minimum of up to ``repeats`` timed calls, stopping once ``budget`` seconds are spent
    (at least one call), after an untimed warm-up call when ``warm_up``.
    ``run_once()`` returns the seconds it measured."""
    if warm_up:
        run_once()
    best = math.inf
    spent = 0.0
    for _ in range(max(1, repeats)):
        seconds = run_once()
        best = min(best, seconds)
        spent += seconds
        if spent >= budget:
            break
    return best


def _time_mslab(scene: Scene, method: str, dt: float, t_end: float, repeats: int, budget: float,
                warm_up: bool) -> float:
    from mslab.simulate import simulate

    steps = step_count(t_end, dt)

    def once() -> float:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StabilityWarning)
            return simulate(scene, method, dt, t_end, save_every=steps, progress=False).stats.wall_time

    return _time_it(once, repeats, budget, warm_up)


def _time_scipy(scene: Scene, solver: str, rtol: float, t_end: float, atol, repeats: int,
                budget: float, warm_up: bool) -> float:
    return _time_it(lambda: _scipy_run(scene, solver, rtol, t_end, atol)["stats"]["wall_time"],
                    repeats, budget, warm_up)


def _picklable(scene: Scene) -> Scene:
    """The scene without its closed form (a closure): errors are computed by the caller."""
    return replace(scene, exact=None) if scene.exact is not None else scene


def _call(task):
    kind, scene, name, value, t_end, n_save, atol = task
    if kind == "mslab":
        return _mslab_run(scene, name, value, t_end, n_save)
    return _scipy_run(scene, name, value, t_end, atol)


def _progress_bar(total: int, progress: bool | None, desc: str):
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="run", file=sys.stderr, leave=False)


def _run_tasks(tasks: list, jobs: int, bar) -> list[dict]:
    """Run error tasks serially or in a process pool (same order as ``tasks``)."""
    results: list = [None] * len(tasks)
    if jobs > 1 and len(tasks) > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(_call, task): i for i, task in enumerate(tasks)}
            from concurrent.futures import as_completed

            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                if bar is not None:
                    bar.update(1)
    else:
        for i, task in enumerate(tasks):
            results[i] = _call(task)
            if bar is not None:
                bar.update(1)
    return results


def _method_names(methods) -> list[str]:
    return [get_method(m).name for m in methods]


# -- experiments -----------------------------------------------------------------------------------------
def work_precision(scene: Scene, methods, dts, t_end: float | None = None, *,
                   scipy_methods=(), rtols=SCIPY_RTOLS, atol: float | None = None,
                   timing: bool = True, repeats: int = 5, budget: float = 1.0, n_save: int = 100,
                   jobs: int = 1, progress: bool | None = False) -> list[dict]:
    """Error, counted work and wall time of every (method, dt), plus scipy reference curves.

    Parameters
    ----------
    scene : Scene
    methods : sequence of str
        mslab registry names.
    dts : sequence of float, or dict of method name -> sequence of float
        Steps; ``t_end / dt`` must be a whole number for each (see :func:`whole_dts`). A dict
        gives each method its own steps (implicit methods often need coarser ones).
    t_end : float, optional
        Default ``scene.settings.t_end``.
    scipy_methods : sequence of str
        ``solve_ivp`` methods run over ``rtols`` on the same forces (e.g. :data:`SCIPY_METHODS`).
    rtols : sequence of float
        Tolerance sweep of the scipy curves; ``atol`` defaults to each ``rtol``.
    timing : bool
        Measure wall times (False: ``wall_time = nan``, much faster).
    repeats, budget : int, float
        At most ``repeats`` timed runs per record, stopping after ``budget`` seconds.
    n_save : int
        About this many saved times enter ``error_rms``.
    jobs : int
        Processes for the error runs (timing runs stay serial; see the module notes).
    progress : bool or None
        tqdm bar on stderr; None: only when stderr is a terminal.

    Returns
    -------
    list of dict
        One flat record per run: ``solver`` ("mslab" or "scipy"), ``method`` (scipy ones
        as ``"scipy:RK45"``), ``dt`` (scipy: mean step ``t_end / steps``), ``rtol`` (scipy
        only), ``error``, ``error_rms``, ``n_force``, ``n_jac``, ``n_solve`` (scipy: LU
        factorisations), ``n_iter``, ``steps``, ``wall_time`` [s], ``ok``, ``failure``,
        ``reference`` ("exact" or "DOP853").
    """
    t_end = float(scene.settings.t_end if t_end is None else t_end)
    names = _method_names(methods)
    steps = _dts_per_method(dts, names)
    for method_dts in steps.values():
        for dt in method_dts:
            step_count(t_end, dt)  # refuse a dt that does not divide t_end before doing any work
    ref = reference_solution(scene, t_end)
    light = _picklable(scene)
    tasks = [("mslab", light, m, dt, t_end, n_save, None) for m in names for dt in steps[m]]
    tasks += [("scipy", light, s, float(r), t_end, n_save, atol) for s in scipy_methods for r in rtols]
    n_timed = len(tasks) if timing else 0
    bar = _progress_bar(len(tasks) + n_timed, progress, f"precision {scene.name}")
    try:
        runs = _run_tasks(tasks, jobs, bar)
        records = []
        for task, run in zip(tasks, runs, strict=True):
            kind, _, name, value, *_ = task
            if kind == "mslab":
                records.append(_record("mslab", name, value, None, run, ref))
            else:
                records.append(_record("scipy", f"scipy:{name}", run["stats"]["dt"], value, run, ref))
        if timing:
            warm = set()  # serial sweeps: the error runs in this process were the warm-up
            for task, rec in zip(tasks, records, strict=True):
                kind, _, name, value, *_ = task
                if rec["ok"]:
                    warm_up = jobs > 1 and (kind, name) not in warm
                    warm.add((kind, name))
                    if kind == "mslab":
                        rec["wall_time"] = _time_mslab(scene, name, value, t_end, repeats, budget, warm_up)
                    else:
                        rec["wall_time"] = _time_scipy(scene, name, value, t_end, atol, repeats, budget,
                                                       warm_up)
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return records


def scipy_records(scene: Scene, t_end: float | None = None, methods=SCIPY_METHODS, rtols=SCIPY_RTOLS,
                  **kwargs) -> list[dict]:
    """Only the scipy reference curves of :func:`work_precision` (same record fields)."""
    return work_precision(scene, (), (), t_end, scipy_methods=methods, rtols=rtols, **kwargs)


def fit_order(dts, errors, floor: float = ROUNDOFF_FLOOR, ceiling: float = math.inf) -> float:
    """Least-squares slope of ``log(error)`` against ``log(dt)``.

    Points with a non-finite error, one below ``floor`` (round-off) or one above
    ``ceiling`` (not yet in the asymptotic range) are left out; nan when fewer than two
    points remain.
    """
    dts = np.asarray(dts, dtype=float)
    errors = np.asarray(errors, dtype=float)
    keep = np.isfinite(errors) & (errors > floor) & (errors < ceiling) & (dts > 0)
    if np.count_nonzero(keep) < 2 or np.unique(dts[keep]).size < 2:
        return math.nan
    slope, _ = np.polyfit(np.log(dts[keep]), np.log(errors[keep]), 1)
    return float(slope)


def error_ceiling(scene: Scene, t_end: float) -> float:
    """A tenth of the solution's size: larger errors are outside the asymptotic range.

    The size is the larger of the scene's extent (bounding-box diagonal of the initial and
    the reference final positions) and the largest reference speed at ``t_end``.
    """
    ref = reference_solution(scene, t_end)
    x = np.concatenate([scene.state0.x, ref.x_end])
    extent = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))
    return 0.1 * max(extent, float(np.max(np.abs(ref.v_end))), 1e-300)


def fitted_orders(records, floor: float = ROUNDOFF_FLOOR, ceiling: float = math.inf) -> dict:
    """:func:`fit_order` of each mslab method in work-precision records; also sets each
    record's ``local_order`` (the slope from the next larger dt)."""
    orders = {}
    names = list(dict.fromkeys(r["method"] for r in records if r.get("solver", "mslab") == "mslab"))
    for m in names:
        rows = sorted((r for r in records if r["method"] == m), key=lambda r: -r["dt"])
        prev = None
        for r in rows:
            r["local_order"] = (fit_order([prev["dt"], r["dt"]], [prev["error"], r["error"]], floor, ceiling)
                                if prev is not None else math.nan)
            prev = r
        orders[m] = fit_order([r["dt"] for r in rows], [r["error"] for r in rows], floor, ceiling)
    return orders


@dataclass
class Convergence:
    """Result of :func:`convergence`.

    Attributes
    ----------
    records : list of dict
        ``method``, ``dt``, ``error`` (final-state max-norm), ``error_rms``, ``local_order``
        (slope from the next larger dt), ``n_force``, ``steps``, ``ok``, ``failure``.
    orders : dict
        Fitted order per method (nan when fewer than two usable points).
    expected : dict
        ``get_method(m).order`` per method.
    """

    records: list
    orders: dict
    expected: dict

    def as_dict(self) -> dict:
        return {"records": self.records, "orders": self.orders, "expected": self.expected}


def convergence(scene: Scene, methods, dts, t_end: float | None = None, *, floor: float = ROUNDOFF_FLOOR,
                ceiling: float | None = None, n_save: int = 100, jobs: int = 1,
                progress: bool | None = False) -> Convergence:
    """Global error at ``t_end`` against ``dt`` and the fitted order of each method.

    Parameters
    ----------
    scene : Scene
    methods : sequence of str
    dts : sequence of float, or dict of method name -> sequence of float
        Steps in the asymptotic range (small enough for every method to be stable and
        its leading error term to dominate, large enough to stay above round-off).
    t_end : float, optional
    floor : float
        Errors below it are round-off and left out of the fit.
    ceiling : float, optional
        Errors above it are left out of the fit (default :func:`error_ceiling`, a tenth of
        the solution's size).

    Returns
    -------
    Convergence
    """
    t_end = float(scene.settings.t_end if t_end is None else t_end)
    records = work_precision(scene, methods, dts, t_end, timing=False, n_save=n_save, jobs=jobs,
                             progress=progress)
    ceiling = error_ceiling(scene, t_end) if ceiling is None else ceiling
    orders = fitted_orders(records, floor, ceiling)
    expected = {m: get_method(m).order for m in orders}
    return Convergence(records, orders, expected)


def _dts_per_method(dts, names: list[str]) -> dict[str, list[float]]:
    """``{method: [dt, ...]}`` from one list for all methods or a dict keyed by method name."""
    if not isinstance(dts, Mapping):
        common = [float(dt) for dt in dts]
        return {m: common for m in names}
    given = {get_method(m).name: [float(dt) for dt in d] for m, d in dts.items()}
    missing = [m for m in names if m not in given]
    if missing:
        raise ValueError(f"dts: no steps given for {', '.join(missing)}")
    return {m: given[m] for m in names}


def whole_dts(dts, t_end: float) -> list[float]:
    """Each dt moved to the nearest ``t_end / n`` (n a whole number), duplicates removed."""
    out = []
    for dt in dts:
        n = max(1, round(t_end / float(dt)))
        value = t_end / n
        if value not in out:
            out.append(value)
    return out


# -- energy drift ----------------------------------------------------------------------------------------
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
        False when the run blew up (its saved part is kept; verdict "drifting").
    failure : str or None
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

    @property
    def max_error(self) -> float:
        return float(np.max(np.abs(self.error))) if self.error.size else math.nan

    def as_record(self) -> dict:
        """Flat summary without the arrays (for tables and JSON)."""
        return {"method": self.method, "steps": self.steps, "n_force": self.n_force,
                "wall_time": self.wall_time, "max_error": self.max_error,
                "final_error": float(self.error[-1]) if self.error.size else math.nan,
                "drift_rate": self.drift_rate, "trend": self.trend, "early": self.early,
                "late": self.late, "verdict": self.verdict, "complete": self.complete,
                "failure": self.failure}


def drift_verdict(t, error, *, trend_limit: float = DRIFT_TREND, growth_limit: float = DRIFT_GROWTH,
                  floor: float = DRIFT_FLOOR) -> dict:
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


def energy_drift(scene: Scene, methods, dt: float | None = None, t_end: float | None = None, *,
                 n_save: int = 2000, trend_limit: float = DRIFT_TREND, growth_limit: float = DRIFT_GROWTH,
                 warm_up: bool = True, progress: bool | None = False) -> dict:
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

    Returns
    -------
    dict
        ``{method: Drift}`` in the order given. A run that blows up keeps what it saved,
        gets ``complete = False`` and the verdict "drifting".
    """
    from mslab.simulate import simulate

    dt = float(scene.settings.dt if dt is None else dt)
    t_end = float(scene.settings.t_end if t_end is None else t_end)
    steps = step_count(t_end, dt)
    names = _method_names(methods)
    bar = _progress_bar(len(names), progress, f"energy drift {scene.name}")
    out = {}
    try:
        for m in names:
            failure = None
            try:
                with warnings.catch_warnings():  # the verdict says it
                    warnings.simplefilter("ignore", StabilityWarning)
                    if warm_up and steps > 20:  # compiled kernels, caches: out of the wall time
                        try:
                            simulate(scene, m, dt, 10 * dt, progress=False)
                        except InstabilityError:
                            pass
                    traj = simulate(scene, m, dt, t_end, save_every=_save_every(steps, n_save),
                                    progress=False)
            except InstabilityError as err:
                traj, failure = err.trajectory, str(err)
            error = traj.energy.relative_drift() if traj.t.size else np.zeros(0)
            rule = drift_verdict(traj.t, error, trend_limit=trend_limit, growth_limit=growth_limit)
            verdict = "drifting" if failure is not None else rule["verdict"]
            out[m] = Drift(m, traj.t, error, rule["drift_rate"], rule["trend"], rule["early"], rule["late"],
                           verdict, traj.stats.steps, traj.stats.n_force, traj.stats.wall_time,
                           failure is None, failure)
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return out
