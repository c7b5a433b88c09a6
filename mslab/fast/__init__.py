"""The compiled fast path: numba kernels for scenes made of springs, gravity and damping.

Decision (documented in the README): the numpy code in ``mslab/effects`` and
``mslab/integrators`` is the readable reference; ``mslab/fast/kernels.py`` repeats the same
equations as loops compiled by numba, and the tests hold both equal (1e-12). Which one
runs is chosen by a *backend*:

* ``"auto"`` (default): numba where it applies and numba imports, numpy otherwise;
* ``"numba"``: numba or an error saying why it does not apply;
* ``"numpy"``: the reference code only.

``simulate(..., backend=...)`` picks it per run; the module switch :data:`BACKEND` (initial
value from the environment variable ``MSLAB_BACKEND``) is the default, and
:func:`use_backend` sets it for a ``with`` block. The compiled *stepping loop* applies to a
System made only of :class:`~mslab.effects.Springs`, :class:`~mslab.effects.Gravity` and
:class:`~mslab.effects.Damping` stepped by an :class:`~mslab.integrators.ExplicitRK`
tableau or one of the symplectic methods; other scenes (colliders) and the implicit
methods keep the numpy loop, where ``Springs.force`` still uses the compiled spring kernel.
"""

from __future__ import annotations

import os
from contextlib import contextmanager

import numpy as np

from mslab.state import State

BACKENDS = ("auto", "numba", "numpy")

#: Default backend of ``simulate`` and of the spring-force kernel.
BACKEND: str = os.environ.get("MSLAB_BACKEND", "auto").strip().lower() or "auto"

_kernels = None
_import_error: str | None = None


def check_backend(name: str | None) -> str:
    """The backend name (``None``: the module default :data:`BACKEND`); ValueError if unknown."""
    name = BACKEND if name is None else str(name).strip().lower()
    if name not in BACKENDS:
        raise ValueError(f"unknown backend '{name}'; valid backends: {', '.join(BACKENDS)}")
    return name


def compiled():
    """The compiled kernels module, or None when numba cannot be imported."""
    global _kernels, _import_error
    if _kernels is None and _import_error is None:
        try:
            from mslab.fast import kernels as module
        except ImportError as err:  # numba missing or broken: the numpy path still works
            _import_error = str(err)
        else:
            _kernels = module
    return _kernels


def available() -> bool:
    """True when numba imports (the compiled kernels can run)."""
    return compiled() is not None


def use_numba(backend: str | None = None) -> bool:
    """Whether the compiled kernels should run under ``backend`` (default :data:`BACKEND`)."""
    name = check_backend(backend)
    if name == "numpy":
        return False
    if not available():
        if name == "numba":
            raise RuntimeError(f"backend 'numba' asked for, but numba does not import: {_import_error}")
        return False
    return True


@contextmanager
def use_backend(name: str):
    """``with use_backend("numpy"): ...`` runs a block with another default backend."""
    global BACKEND
    old, BACKEND = BACKEND, check_backend(name)
    try:
        yield
    finally:
        BACKEND = old


class ForceModel:
    """Flat arrays of the force terms the kernels know: springs + gravity + damping.

    Attributes
    ----------
    inv_mass, mass : ndarray, shape (n_particles,)
    free : ndarray of bool, shape (n_particles,)
    i, j : ndarray of int64, shape (n_springs,)
    stiffness, rest_length, damping : ndarray, shape (n_springs,)
    damped : bool
        Some spring has damping.
    f_gravity : ndarray, shape (n_particles, dim)
        ``m_i g`` summed over gravity effects (zeros without gravity).
    gamma : float
        Viscous drag coefficient summed over damping effects.
    """

    def __init__(self, system):
        from mslab.effects import Damping, Gravity, Springs

        n, dim = system.n_particles, system.dim
        springs = [e for e in system.effects if type(e) is Springs]
        self.inv_mass = np.ascontiguousarray(system.inv_mass, dtype=float)
        self.mass = np.ascontiguousarray(system.mass, dtype=float)
        self.free = np.ascontiguousarray(~system.pinned)
        self.i = np.ascontiguousarray(np.concatenate([s.i for s in springs] or [np.empty(0)]), np.int64)
        self.j = np.ascontiguousarray(np.concatenate([s.j for s in springs] or [np.empty(0)]), np.int64)
        self.stiffness, self.rest_length, self.damping = (
            np.ascontiguousarray(np.concatenate([getattr(s, name) for s in springs] or [np.empty(0)]),
                                 dtype=float)
            for name in ("stiffness", "rest_length", "damping"))
        self.damped = bool(np.any(self.damping != 0.0))
        self.f_gravity = np.zeros((n, dim))
        for e in system.effects:
            if type(e) is Gravity:
                self.f_gravity += e._f
        self.gamma = float(sum(e.gamma for e in system.effects if type(e) is Damping))

    def args(self) -> tuple:
        """The trailing arguments of :func:`kernels.rhs` and the stepping loops."""
        return (self.inv_mass, self.i, self.j, self.stiffness, self.rest_length, self.damping,
                self.damped, self.f_gravity, self.gamma)

    def rhs(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Acceleration (n_particles, dim) and dissipated power: ``System.rhs`` compiled, not counted."""
        a = np.empty_like(x)
        p = compiled().rhs(_f64(x), _f64(v), *self.args(), a)
        return a, float(p)

    def energies(self, xs: np.ndarray, vs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Kinetic and potential energy of saved states ``xs, vs`` (n_saved, n_particles, dim)."""
        return compiled().energies(_f64(xs), _f64(vs), self.mass, self.free, self.i, self.j,
                                  self.stiffness, self.rest_length, self.f_gravity)


#: the one-stage tableau of a kick whose forces do not depend on velocity
_EULER = (np.zeros((1, 1)), np.ones(1))


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def unsupported(system, integrator) -> str | None:
    """Why the compiled stepping loop cannot run this system and method (None: it can)."""
    from mslab.effects import Damping, Gravity, Springs
    from mslab.system import System

    if type(system) is not System or {"rhs", "acceleration", "force"} & set(vars(system)):
        return "the system is not a plain mslab.System"
    others = [e.name for e in system.effects if type(e) not in (Springs, Gravity, Damping)]
    if others:
        return f"effects {others} have no compiled kernel (only springs, gravity, damping)"
    if integrator.compiled is None or "step" in vars(integrator):
        return f"method '{integrator.name}' has no compiled stepping loop"
    return None


class Stepper:
    """Runs the steps of ``simulate`` in compiled chunks (see :func:`stepper`).

    The loop is the one the method names (``Integrator.compiled``): ``"explicit_rk"`` over
    ``(A, b)``, ``"splitting"`` over ``(drift, kick)``, ``"verlet"`` or ``"leapfrog"``.
    Counts ``n_force`` on the System exactly as the numpy loop does (the loops return it).
    """

    #: most steps per compiled call
    max_chunk: int = 10000

    def __init__(self, system, integrator):
        self.system = system
        self.integrator = integrator
        self.model = ForceModel(system)
        self.loop, self.arrays = integrator.compiled
        work = system.n_particles + self.model.i.shape[0]
        #: steps per compiled call: about 10^6 particle+spring updates, so Ctrl-C and the
        #: progress bar answer within a fraction of a second
        self.chunk = int(min(self.max_chunk, max(1, 10**6 // max(1, work * integrator.n_stages))))
        self._x = self._v = None
        self._mem = None

    def advance(self, state: State, dt: float, step: int, stop: int, saved: np.ndarray, k: int,
                xs: np.ndarray, vs: np.ndarray, ds: np.ndarray, limit: float):
        """Steps ``step+1 .. stop`` from ``state`` (the state after ``step``).

        Fills ``xs, vs, ds`` at the indices ``saved[k:]`` reached. Returns
        ``(step, k, state, ok)``; ``ok`` is False when step ``step`` blew up.
        """
        kn = compiled()
        if self._x is None:
            self._x, self._v = _f64(state.x).copy(), _f64(state.v).copy()
            self._mem = self._memory(state)
        x, v = self._x, self._v
        args = self.model.args()
        common = (float(dt), step, stop, saved, k, xs, vs, ds, float(limit))
        ig = self.integrator
        if self.loop == "explicit_rk":
            A, b = self.arrays
            out = kn.run_explicit_rk(x, v, float(state.dissipated), _f64(A), _f64(b), *common, *args)
        elif self.loop == "splitting":
            drift, kick = self.arrays
            mem_a, mem_p = self._mem
            reuse = bool(ig.fsal and not self.system.velocity_dependent)
            kA, kb = (ig.kick_method.A, ig.kick_method.b) if self.system.velocity_dependent else _EULER
            out = kn.run_splitting(x, v, float(state.dissipated), _f64(drift), _f64(kick), reuse, _f64(kA),
                                   _f64(kb), mem_a, mem_p, *common, *args)
        else:
            mem_x, mem_a, mem_p = self._mem
            code = kn.VERLET if self.loop == "verlet" else kn.LEAPFROG
            out = kn.run_two_step(code, x, v, float(state.dissipated), mem_x, mem_a, mem_p, *common,
                                  self.system.velocity_dependent, *args)
        new_step, k, dissipated, status, n_force = out
        self.system.counters.n_force += n_force
        return new_step, k, State(x.copy(), v.copy(), self._memory_tuple(), dissipated), status == kn.OK

    def _memory(self, state: State):
        """Memory arrays of the kernel from the numpy ``start``."""
        shape = state.x.shape
        if self.loop == "splitting":
            mem_a, mem_p = np.zeros(shape), np.zeros(1)
            if state.memory:
                mem_a[:], mem_p[0] = state.memory
            return mem_a, mem_p
        mem_x, mem_a, mem_p = np.zeros(shape), np.zeros(shape), np.zeros(1)
        if self.loop == "verlet":
            mem_x[:], mem_p[0] = state.memory
        elif self.loop == "leapfrog":
            mem_x[:], mem_a[:], mem_p[0] = state.memory
        return mem_x, mem_a, mem_p

    def _memory_tuple(self) -> tuple:
        if self.loop == "explicit_rk":
            return ()
        if self.loop == "splitting":
            if not (self.integrator.fsal and not self.system.velocity_dependent):
                return ()
            mem_a, mem_p = (m.copy() for m in self._mem)
            return (mem_a, float(mem_p[0]))
        mem_x, mem_a, mem_p = (m.copy() for m in self._mem)
        if self.loop == "verlet":
            return (mem_x, float(mem_p[0]))
        return (mem_x, mem_a, float(mem_p[0]))


def stepper(system, integrator, backend: str | None = None) -> Stepper | None:
    """A compiled :class:`Stepper` for this run, or None for the numpy loop.

    ``backend="numba"`` raises ValueError when the compiled loop does not apply.
    """
    name = check_backend(backend)
    if not use_numba(name):
        return None
    reason = unsupported(system, integrator)
    if reason is not None:
        if name == "numba":
            raise ValueError(f"backend 'numba': {reason}; use backend='auto' or 'numpy'")
        return None
    return Stepper(system, integrator)
