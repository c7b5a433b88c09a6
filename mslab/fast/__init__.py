"""The compiled fast path: the effects' own kernels composed into generic stepping loops (numba).

Decision (documented in the README): the numpy code in ``mslab/effects`` and
``mslab/integrators`` is the readable reference. Each effect may define its force once more
as a numba-style ``kernel`` (in its own module); :mod:`mslab.fast.compose` sums the kernels
of a scene into the generic loops of :mod:`mslab.fast.loops` (one per method family) and
numba compiles and caches them. The tests hold both paths equal (1e-12). Without numba
``"auto"`` takes the numpy loop (one ``PerformanceWarning``) and ``"numba"`` is refused
(:func:`mslab.jit.without_numba`).

Which path runs is the *backend*, an argument fixed when the stepper is built
(``simulate(..., backend=...)``; ``None`` reads the environment variable
``MSLAB_BACKEND``, default ``"auto"``):

* ``"numba"``: the compiled loop, or ValueError saying why it does not apply;
* ``"numpy"``: the readable loop only;
* ``"auto"``: the compiled loop where it applies and the run's numpy time is predicted above
  :data:`AUTO_SECONDS` (:func:`worth_compiling`), numpy otherwise.

The compiled loop applies to a plain :class:`~mslab.system.System` whose effects all have
kernels (springs, gravity, damping, anchors, colliders today) stepped by a method whose ``compiled``
names a loop (explicit Runge-Kutta tableaux, splittings, Verlet, leapfrog).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from mslab import jit
from mslab.fast.model import ForceModel, kernel_reason
from mslab.fast.runner import Stepper

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator
    from mslab.state import State
    from mslab.system import System

BACKENDS = ("auto", "numba", "numpy")
#: the precisions of the compiled loop (``dtype``); float32 only there (:func:`check_dtype`)
DTYPES = ("float64", "float32")

#: Seconds a process pays before the compiled loops of a scene run (measured in
#: benchmarks/RESULTS.md, "A compiled loop that loads at once"): loading them from numba's
#: cache (0.28-0.33 s, medians by scene: numba's import ~0.2 s and the loop's load ~0.1 s,
#: over what a numpy run imports anyway; 0.52-0.57 s before issue 38), or compiling them (a
#: combination of kernels never run on this machine). ``auto`` takes numpy when the numpy
#: loop is predicted to finish sooner.
LOAD_SECONDS = 0.3
COMPILE_SECONDS = 6.5


def check_backend(name: str | None) -> str:
    """Return the backend name (``None``: ``$MSLAB_BACKEND`` or ``"auto"``); ValueError if unknown."""
    if name is None:
        name = os.environ.get("MSLAB_BACKEND", "").strip() or "auto"
    name = str(name).strip().lower()
    if name not in BACKENDS:
        raise ValueError(f"unknown backend '{name}'; valid backends: {', '.join(BACKENDS)}")
    return name


def check_dtype(dtype: object, backend: str) -> np.dtype:
    """Return the run's precision as a numpy dtype; ValueError naming ``dtype`` where it cannot run.

    ``"float64"`` (default, every backend) or ``"float32"`` (also ``np.float32``): the compiled
    loop only, so ``backend="numpy"`` is refused; whether the scene and method have a compiled
    loop is asked by :func:`stepper`. (docs/precision.md, "float32": its measured error.)
    """
    try:
        name = np.dtype(dtype).name
    except TypeError:
        name = None
    if name not in DTYPES or isinstance(dtype, bool):
        raise ValueError(f"dtype must be one of {', '.join(DTYPES)}, got {dtype!r}")
    if name != "float64" and backend == "numpy":
        raise ValueError(f"dtype '{name}' runs only in the compiled loop: backend 'numpy' steps float64; "
                         f"use backend='numba' or 'auto', or dtype='float64'")
    return np.dtype(name)


def _single_reason(system: System, integrator: Integrator) -> str | None:
    """Why a float32 run cannot step this system with this method (None: it can)."""
    reason = unsupported(system, integrator)
    if reason is None and integrator.compiled[0] == "implicit":
        reason = f"method '{integrator.name}' is implicit (its Newton solves are float64 only)"
    return reason


def forces_reason(system: System) -> str | None:
    """Why the compiled forces cannot stand in for this system's (None: they can)."""
    from mslab.system import System

    if type(system) is not System or {"rhs", "acceleration", "force"} & set(vars(system)):
        return "the system is not a plain mslab.System"
    return kernel_reason(system)


def unsupported(system: System, integrator: Integrator) -> str | None:
    """Why the compiled stepping loop cannot run this system and method (None: it can)."""
    reason = forces_reason(system)
    if reason is not None:
        return reason
    if integrator.compiled is None or "step" in vars(integrator):
        return f"method '{integrator.name}' has no compiled stepping loop"
    return None


#: Predicted seconds of numpy stepping, fitted on this machine's scenes (chain, pendulum,
#: hanging rope, jelly cube, cube without shear, topology pair, cloth on a sphere) and the
#: explicit methods (euler to rk6, the splittings, Verlet, leapfrog): CPU seconds of 200
#: steps, minimum of 3, issue 38 item 0 (``benchmarks/lone_call.py``). A fixed cost per step
#: (the method's own Python and array work, the stopping checks), per force evaluation (the
#: system's Python around the forces), per effect and evaluation, and per item (particle,
#: spring, anchor) of an effect's kernel and evaluation. The fit is within 0.5-1.6x of every
#: measured run; each term is rounded up.
NUMPY_SECONDS_PER_STEP = 30e-6
NUMPY_SECONDS_PER_EVAL = 50e-6
NUMPY_SECONDS_PER_EFFECT = 8e-6
NUMPY_SECONDS_PER_ITEM = 80e-9

#: ``auto`` steps compiled every run whose numpy time is predicted above this. Below
#: :data:`LOAD_SECONDS` on purpose: the rule cannot know whether this process has loaded the
#: compiled loop already (it must not: the same call gives the same bits whatever ran
#: before), and once loaded, a numpy run costs 40-170x the compiled one; a run predicted
#: above 0.1 s (so every run of >= 0.2 s, given the model's spread) takes the compiled loop,
#: paying at most the load of the compiled code (~0.3 s) in a fresh process.
AUTO_SECONDS = 0.1


def _items(effect: object, n_particles: int) -> int:
    """Return the number of items an effect's kernel loops over (``Effect.kernel_items``)."""
    return effect.kernel_items(n_particles)


def worth_compiling(system: System, integrator: Integrator, n_steps: int,
                    state0: State | None = None) -> bool:
    """Decide whether ``auto`` runs these steps compiled (cost: one pass over the effects).

    True when the numpy loop's predicted time (:func:`numpy_seconds`) exceeds
    :data:`AUTO_SECONDS`. The prediction is a fixed cost model, never a measurement and never
    this process's history: the same run always takes the same backend, so its results
    (equal on both backends only to round-off) are reproducible.
    """
    return numpy_seconds(system, integrator, n_steps) > AUTO_SECONDS


def numpy_seconds(system: System, integrator: Integrator, n_steps: int) -> float:
    """Predict the seconds of ``n_steps`` numpy steps (cost: one pass over the effects).

    ``n_steps`` times (:data:`NUMPY_SECONDS_PER_STEP` + the method's force evaluations per
    step on this system, :meth:`~mslab.integrators.base.Integrator.evaluations_per_step`,
    times the cost of one evaluation: :data:`NUMPY_SECONDS_PER_EVAL`, and per effect
    :data:`NUMPY_SECONDS_PER_EFFECT` + :data:`NUMPY_SECONDS_PER_ITEM` per item).
    """
    per_eval = NUMPY_SECONDS_PER_EVAL + sum(NUMPY_SECONDS_PER_EFFECT + NUMPY_SECONDS_PER_ITEM
                                            * _items(e, system.n_particles) for e in system.effects)
    return n_steps * (NUMPY_SECONDS_PER_STEP + integrator.evaluations_per_step(system) * per_eval)


def stepper(system: System, integrator: Integrator, backend: str | None = None, n_steps: int | None = None,
            state0: State | None = None, dtype: object = "float64") -> Stepper | None:
    """Return a compiled :class:`~mslab.fast.runner.Stepper` for this run, or None for the numpy loop.

    ``backend="numba"`` raises ValueError when the compiled loop does not apply; ``"auto"``
    with ``n_steps`` and ``state0`` also weighs the run's length (:func:`worth_compiling`),
    except for a method that steps only compiled (``compiled_only``, e.g. the clamped Newton matrix).
    ``dtype="float32"`` (:func:`check_dtype`) always takes the compiled loop, or raises
    ValueError naming ``dtype`` where there is none (an implicit method, an effect without kernel).
    """
    name = check_backend(backend)
    precision = check_dtype(dtype, name)
    if precision != np.float64:
        reason = _single_reason(system, integrator)
        if reason is not None:
            raise ValueError(f"dtype '{precision.name}' runs only in the compiled loop: {reason}")
        if not jit.available():
            jit.without_numba("numba")
        runner = Stepper(system, integrator, precision)
        runner.warm()
        return runner
    if name == "numpy":
        return None
    reason = unsupported(system, integrator)
    if reason is not None:
        if name == "numba":
            raise ValueError(f"backend 'numba': {reason}; use backend='auto' or 'numpy'")
        return None
    try:
        if (name == "auto" and n_steps is not None and not getattr(integrator, "compiled_only", False)
                and not worth_compiling(system, integrator, n_steps, state0)):
            return None
        if not jit.available():  # numba missing: "numba" one clear error, "auto" the numpy loop
            return jit.without_numba(name)
        runner = Stepper(system, integrator)
        runner.warm()  # loading or compiling is not stepping: out of the run's wall time
    except OSError as err:  # no folder for the generated loops (compose.cache_dir)
        if name == "numba":
            raise ValueError(f"backend 'numba': cannot write the compiled loops ({err}); "
                             f"set MSLAB_CACHE_DIR to a writable folder") from None
        return None
    return runner


__all__ = ["AUTO_SECONDS", "BACKENDS", "COMPILE_SECONDS", "DTYPES", "ForceModel", "LOAD_SECONDS", "Stepper",
           "check_backend", "check_dtype", "stepper", "numpy_seconds", "unsupported", "worth_compiling"]
