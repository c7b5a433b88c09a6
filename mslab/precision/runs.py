"""One run at a time: error runs of mslab and scipy, timed runs, sweeps over processes.

An error run keeps about ``n_save`` samples and the counted work; a timed run computes
nothing else and is repeated (minimum kept, DiffEqDevTools style) after an untimed
warm-up where one is needed, so compilation and first-call costs stay out of the times.
"""

from __future__ import annotations

import math
import multiprocessing
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from mslab.errors import InstabilityError, StabilityWarning
from mslab.integrators.base import get_method
from mslab.precision.reference import Reference, _flat_jacobian, _flat_rhs, _y0
from mslab.scenes.builder import Scene
from mslab.simulate import step_count

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator


def _save_every(steps: int, n_save: int) -> int:
    return max(1, steps // max(1, n_save))


def _mslab_run(scene: Scene, method: str, dt: float, t_end: float, n_save: int,
               backend: str | None = None) -> dict:
    """One error run of an mslab method: saved samples and counted work (picklable result)."""
    from mslab.simulate import simulate

    steps = step_count(t_end, dt)
    try:
        with warnings.catch_warnings():  # a predicted instability shows in the record itself
            warnings.simplefilter("ignore", StabilityWarning)
            traj = simulate(scene, method, dt, t_end, save_every=_save_every(steps, n_save), progress=False,
                            backend=backend)
    except InstabilityError as err:  # ConvergenceError too
        stats = err.trajectory.stats.as_dict() if err.trajectory is not None else {}
        return {"ok": False, "failure": str(err), "stats": stats}
    return {"ok": True, "failure": None, "t": traj.t, "x": traj.x, "v": traj.v,
            "stats": traj.stats.as_dict()}


def _scipy_run(scene: Scene, solver: str, rtol: float, t_end: float, atol: float | None,
               backend: str = "numpy") -> dict:
    """One solve_ivp run on the scene's forces; saved samples are the solver's own steps.

    No ``t_eval`` and no dense output: DOP853's interpolant would cost extra force
    evaluations and inflate ``nfev``. ``backend``: the right-hand side's
    (:func:`mslab.precision.reference._flat_rhs`), built before the clock starts.
    """
    from scipy.integrate import solve_ivp

    shape = scene.state0.x.shape
    n = int(np.prod(shape))
    system = scene.system
    kwargs = {}
    if solver in ("Radau", "BDF", "LSODA"):
        kwargs["jac"] = _flat_jacobian(system, shape)
    rhs = _flat_rhs(system, shape, backend)
    start = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_end), _y0(scene), method=solver, rtol=rtol,
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


def _time_it(run_once: Callable[[], float], repeats: int, budget: float, warm_up: bool) -> float:
    """Return the minimum of up to ``repeats`` timed calls.

    Stops once ``budget`` seconds are spent (at least one call), after an untimed warm-up
    call when ``warm_up``. ``run_once()`` returns the seconds it measured.
    """
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
                warm_up: bool, backend: str | None = None) -> float:
    from mslab.simulate import simulate

    steps = step_count(t_end, dt)

    def once() -> float:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StabilityWarning)
            return simulate(scene, method, dt, t_end, save_every=steps, progress=False,
                            backend=backend).stats.wall_time

    return _time_it(once, repeats, budget, warm_up)


def _time_scipy(scene: Scene, solver: str, rtol: float, t_end: float, atol: float | None, repeats: int,
                budget: float, warm_up: bool, backend: str = "numpy") -> float:
    return _time_it(lambda: _scipy_run(scene, solver, rtol, t_end, atol, backend)["stats"]["wall_time"],
                    repeats, budget, warm_up)


def _picklable(scene: Scene) -> Scene:
    """Return the scene without its closed form (a closure): errors are computed by the caller."""
    return replace(scene, exact=None) if scene.exact is not None else scene


def _call(task: tuple):
    kind, scene, name, value, t_end, n_save, extra = task  # extra: mslab's backend, scipy's (atol, backend)
    if kind == "mslab":
        return _mslab_run(scene, name, value, t_end, n_save, extra)
    return _scipy_run(scene, name, value, t_end, *extra)


def _progress_bar(total: int, progress: Any, desc: str, unit: str = "run"):
    """Return ``(bar, owned)``: a :class:`mslab.progress.Progress` or the caller's bar, or no bar.

    The :class:`mslab.progress.Progress` is drawn by the clock, on a terminal; the caller's
    own bar is not closed here; ``(None, False)`` for ``progress=False``.
    """
    from mslab.progress import make_progress

    return make_progress(progress, total, desc, unit)


def _describe(bar: Any, text: str) -> None:
    if bar is not None and hasattr(bar, "describe"):
        bar.describe(text)


def usable_cpus() -> int:
    """Return how many CPUs this process may run on (its affinity where the system tells it)."""
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _run_tasks(tasks: list, jobs: int, bar: Any) -> list[dict]:
    """Run error tasks serially or in a process pool (same order as ``tasks``)."""
    results: list = [None] * len(tasks)
    if jobs > 1 and len(tasks) > 1:
        # workers from a fresh server process, not forks of this one: a fork of a process whose
        # compiled loops started GNU OpenMP's threads aborts at its own first parallel loop
        context = multiprocessing.get_context("forkserver" if sys.platform.startswith("linux") else None)
        with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
            futures = {pool.submit(_call, task): i for i, task in enumerate(tasks)}
            from concurrent.futures import as_completed

            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                if bar is not None:
                    bar.update(1)
    else:
        for i, task in enumerate(tasks):
            kind, _, name, value, *_ = task
            _describe(bar, f"{name} {'dt' if kind == 'mslab' else 'rtol'} = {value:.3g}")
            results[i] = _call(task)
            if bar is not None:
                bar.update(1)
    return results


def _method_names(methods: Iterable[str | Integrator]) -> list[str]:
    return [get_method(m).name for m in methods]


def _dts_per_method(dts: Sequence[float] | Mapping[str, Sequence[float]],
                    names: list[str]) -> dict[str, list[float]]:
    """Return ``{method: [dt, ...]}`` from one list for all methods or a dict keyed by method name."""
    if not isinstance(dts, Mapping):
        common = [float(dt) for dt in dts]
        return {m: common for m in names}
    given = {get_method(m).name: [float(dt) for dt in d] for m, d in dts.items()}
    missing = [m for m in names if m not in given]
    if missing:
        raise ValueError(f"dts: no steps given for {', '.join(missing)}")
    return {m: given[m] for m in names}


def whole_dts(dts: Iterable[float], t_end: float) -> list[float]:
    """Move each dt to the nearest ``t_end / n`` (n a whole number), duplicates removed."""
    out = []
    for dt in dts:
        n = max(1, round(t_end / float(dt)))
        value = t_end / n
        if value not in out:
            out.append(value)
    return out
