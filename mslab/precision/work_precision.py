"""Work-precision: error, counted work and wall time of every (method, dt), scipy alongside."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from mslab.fast.job import job_backends, rhs_backend
from mslab.integrators.base import get_method
from mslab.precision.reference import Reference, reference_solution
from mslab.precision.runs import (
    _describe,
    _dts_per_method,
    _method_names,
    _picklable,
    _progress_bar,
    _record,
    _run_tasks,
    _time_mslab,
    _time_scipy,
    usable_cpus,
)
from mslab.scenes.builder import Scene
from mslab.simulate import step_count

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator

#: scipy's ``solve_ivp`` methods drawn as reference curves
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF")
#: default tolerance sweep of the scipy curves (``atol = rtol``)
SCIPY_RTOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)


def work_precision(scene: Scene, methods: Sequence[str | Integrator],
                   dts: Sequence[float] | Mapping[str, Sequence[float]], t_end: float | None = None, *,
                   scipy_methods: Sequence[str] = (), rtols: Sequence[float] = SCIPY_RTOLS,
                   atol: float | None = None,
                   timing: bool = True, repeats: int = 5, budget: float = 1.0, n_save: int = 100,
                   jobs: int = 1, progress: bool | None = False, backend: str | None = None) -> list[dict]:
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
        Processes for the error runs, at most the CPUs this process may use (a larger number is
        capped to that count); timing runs stay serial (see the module notes).
    backend : {"auto", "numba", "numpy"}, optional
        Backend of the runs (None: ``$MSLAB_BACKEND`` or ``"auto"``). ``"auto"`` is decided
        once for the whole sweep (:func:`mslab.fast.job.job_backends`): when all its runs
        together repay loading the compiled code, every run that the compiled loop can step
        takes it. Error runs and timed runs of a (method, dt) take the same backend.
    progress : bool, None or object with ``update(n)``
        Progress by the clock (:mod:`mslab.progress`) naming the current run; None: on a
        terminal once the sweep has taken about 2 s, False: none, an object: the caller's.

    Returns
    -------
    list of dict
        One flat record per run: ``solver`` ("mslab" or "scipy"), ``method`` (scipy ones
        as ``"scipy:RK45"``), ``dt`` (scipy: mean step ``t_end / steps``), ``rtol`` (scipy
        only), ``error``, ``error_rms``, ``n_force``, ``n_jac``, ``n_solve`` (scipy: LU
        factorisations), ``n_iter``, ``steps``, ``wall_time`` [s], ``ok``, ``failure``,
        ``reference`` ("exact" or "DOP853"); mslab's records also ``backend`` ("numba" or
        "numpy": the code that stepped the run); scipy's records ``backend`` of the right-hand
        side they were given: mslab's compiled forces when the sweep's own runs step compiled
        (:func:`mslab.fast.job.rhs_backend`), so every curve has the same forces at the same speed.
    """
    t_end = float(scene.settings.t_end if t_end is None else t_end)
    names = _method_names(methods)
    steps = _dts_per_method(dts, names)
    for method_dts in steps.values():
        for dt in method_dts:
            step_count(t_end, dt)  # refuse a dt that does not divide t_end before doing any work
    ref = reference_solution(scene, t_end)
    light = _picklable(scene)
    runs = [(m, dt) for m in names for dt in steps[m]]
    backends = job_backends(scene.system,
                            [(get_method(m), step_count(t_end, dt) * (1 + (repeats if timing else 0)))
                             for m, dt in runs], backend)
    tasks = [("mslab", light, m, dt, t_end, n_save, b) for (m, dt), b in zip(runs, backends, strict=True)]
    scipy_backend = rhs_backend(scene.system, backends, backend)  # scipy on the same forces, same speed
    tasks += [("scipy", light, s, float(r), t_end, n_save, (atol, scipy_backend))
              for s in scipy_methods for r in rtols]
    n_timed = len(tasks) if timing else 0
    bar, owned = _progress_bar(len(tasks) + n_timed, progress, f"precision {scene.name}")
    try:
        return _sweep(scene, tasks, ref, t_end, atol, timing, repeats, budget, jobs, bar)
    finally:
        if owned:
            bar.close()


class PrecisionInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`work_precision`: ``.records`` of the methods finished, ``.methods`` their names.

    A method (or scipy solver, named ``"scipy:RK45"``) is finished when every one of its runs
    has its error and, with timing, its wall time; ``.total`` is how many the sweep had.
    """

    def __init__(self, records: list[dict], methods: list[str], total: int):
        super().__init__("interrupted")
        self.records, self.methods, self.total = records, methods, total


def _sweep(scene: Scene, tasks: list, ref: Reference, t_end: float, atol: float | None, timing: bool,
           repeats: int, budget: float, jobs: int, bar: Any) -> list[dict]:
    """Run the tasks method by method: each method's error runs, then its timed runs.

    Serial error runs go method by method, so a Ctrl-C keeps every method finished before it
    (:class:`PrecisionInterrupted`); parallel ones run in one pool first. The records come in
    the order of ``tasks`` either way, and each equals what the same run gives alone.
    """
    groups: dict[str, list[int]] = {}
    for i, (kind, _, name, *_) in enumerate(tasks):
        groups.setdefault(name if kind == "mslab" else f"scipy:{name}", []).append(i)
    records: list[dict] = []
    finished: list[str] = []
    jobs = min(jobs, usable_cpus())  # more processes than CPUs only share them (and fill the memory)
    try:
        runs = _run_tasks(tasks, jobs, bar) if jobs > 1 else None
        for label, indices in groups.items():
            chosen = [tasks[i] for i in indices]
            done = _records(chosen, [runs[i] for i in indices] if runs else _run_tasks(chosen, 1, bar), ref)
            if timing:
                _time_records(scene, chosen, done, t_end, atol, repeats, budget, jobs > 1, bar)
            records.extend(done)
            finished.append(label)
    except KeyboardInterrupt:
        raise PrecisionInterrupted(records, finished, len(groups)) from None
    return records


def _records(tasks: list, runs: list[dict], ref: Reference) -> list[dict]:
    """One record per task and its run, with the backend it ran on (scipy: its right-hand side's)."""
    records = []
    for task, run in zip(tasks, runs, strict=True):
        kind, _, name, value, *_ = task
        if kind == "mslab":
            records.append({**_record("mslab", name, value, None, run, ref), "backend": task[-1]})
        else:
            records.append({**_record("scipy", f"scipy:{name}", run["stats"]["dt"], value, run, ref),
                            "backend": task[-1][1]})
    return records


def _time_records(scene: Scene, tasks: list, records: list[dict], t_end: float, atol: float | None,
                  repeats: int, budget: float, parallel: bool, bar: Any) -> None:
    """Measure the ``wall_time`` of every record that ran, serially (its runs are timed in this process)."""
    warm = set()  # serial sweeps: the error runs in this process were the warm-up
    for task, rec in zip(tasks, records, strict=True):
        kind, _, name, value, *_ = task
        if rec["ok"]:
            _describe(bar, f"timing {name} {'dt' if kind == 'mslab' else 'rtol'} = {value:.3g}")
            warm_up = parallel and (kind, name) not in warm
            warm.add((kind, name))
            if kind == "mslab":
                rec["wall_time"] = _time_mslab(scene, name, value, t_end, repeats, budget, warm_up, task[-1])
            else:
                rec["wall_time"] = _time_scipy(scene, name, value, t_end, atol, repeats, budget, warm_up,
                                               task[-1][1])
        if bar is not None:
            bar.update(1)


def scipy_records(scene: Scene, t_end: float | None = None, methods: Sequence[str] = SCIPY_METHODS,
                  rtols: Sequence[float] = SCIPY_RTOLS, **kwargs) -> list[dict]:
    """Return only the scipy reference curves of :func:`work_precision` (same record fields)."""
    return work_precision(scene, (), (), t_end, scipy_methods=methods, rtols=rtols, **kwargs)
