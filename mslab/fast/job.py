"""The backend of a whole job: one decision for every run of a sweep.

A sweep (a work-precision diagram, a convergence study, an energy-drift comparison) runs
many short simulations of one scene. Deciding per run, ``auto`` would send each of them to
numpy (no single run repays loading the compiled code) and the sweep would run 40-170x
slower than compiled. The job is known in advance, so it is decided once: when the numpy
time predicted for *all* its runs (the fixed cost model :func:`mslab.fast.numpy_seconds`,
never a measurement) exceeds :data:`mslab.fast.AUTO_SECONDS` (the rule of a single run), every run
that the compiled loop can step takes it, the others numpy. The same job takes the same
backends on every machine, so its results (equal on both backends to round-off) are
reproducible.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

from mslab import jit
from mslab.fast import AUTO_SECONDS, check_backend, forces_reason, numpy_seconds, unsupported

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator
    from mslab.system import System


def job_backends(system: System, runs: Iterable[tuple[Integrator, int]],
                 backend: str | None = None) -> list[str]:
    """Return the backend of each run of a job on one system: ``"numba"`` or ``"numpy"``.

    Parameters
    ----------
    system : System
        The scene's system, shared by every run.
    runs : iterable of (Integrator, int)
        Each run's method and its number of steps (repeats of a timed run listed as runs).
    backend : {"auto", "numba", "numpy"}, optional
        The job's backend (None: ``$MSLAB_BACKEND`` or ``"auto"``). ``"numba"`` and
        ``"numpy"`` are kept as asked (``"numba"`` still refuses, run by run, where the
        compiled loop does not apply); ``"auto"`` is decided for the whole job (the numpy loop, with one
        ``PerformanceWarning``, where numba is not installed).
    """
    runs = list(runs)
    name = check_backend(backend)
    if name != "auto":
        return [name] * len(runs)
    able = [unsupported(system, integrator) is None for integrator, _ in runs]
    total = sum(numpy_seconds(system, integrator, n) for (integrator, n), ok in zip(runs, able, strict=True)
                if ok)
    compiled = total > AUTO_SECONDS
    if compiled and not jit.available():  # numba missing: the numpy loop, with one warning what it costs
        jit.without_numba(name)
        compiled = False
    return ["numba" if ok and compiled else "numpy" for ok in able]


def rhs_backend(system: System, backends: list[str], backend: str | None = None) -> str:
    """Return the backend of the job's right-hand sides handed to other solvers (scipy's ``solve_ivp``).

    ``"numba"`` (mslab's compiled forces, :meth:`mslab.fast.ForceModel.rhs`) when the job's
    own runs step compiled (``backends``, from :func:`job_backends`) or ``"numba"`` was asked,
    and the system's forces compile; else ``"numpy"`` (``System.acceleration``). So the curves
    of a work-precision diagram compare solvers on the same forces at the same speed.
    """
    name = check_backend(backend)
    wanted = name == "numba" or (name == "auto" and "numba" in backends and jit.available())
    return "numba" if wanted and forces_reason(system) is None else "numpy"
