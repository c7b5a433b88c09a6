"""The compiled steps of a stepping session: chunks of the family's loop over the scene's kernels."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab import jit
from mslab.fast.model import ForceModel
from mslab.fast.newton import CompiledSystem
from mslab.state import State

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator
    from mslab.system import System

#: the one-stage tableau of a kick whose forces do not depend on velocity: ``v += b h a``
_EULER = (np.zeros((1, 1)), np.ones(1))


class Stepper:
    """Runs the steps of a session (:class:`mslab.simulation.Simulation`) in compiled chunks.

    Built by :func:`mslab.fast.stepper`; holds the state, the method's memory and the
    loop's buffers between calls, so a session stepped frame by frame pays no set-up per call.

    The loop is the one the method names (``Integrator.compiled``): ``"explicit_rk"`` over
    ``(A, b)``, ``"splitting"`` over ``(drift, kick)``, ``"verlet"`` or ``"leapfrog"``; for
    ``"implicit"`` there is no loop: the session steps the method on :attr:`view`, a
    :class:`~mslab.fast.newton.CompiledSystem`.
    Counts ``n_force`` on the System exactly as the numpy loop does (the loops return it).
    ``dtype`` is the precision of the loop's state, forces and buffers (float64, or float32);
    what it hands out (:attr:`x`, :attr:`v`, :meth:`state`, the saved samples) is float64.
    """

    #: most steps per compiled call
    max_chunk: int = 10000

    def __init__(self, system: System, integrator: Integrator, dtype: type = np.float64):
        self.system = system
        self.integrator = integrator
        self.dtype = np.dtype(dtype)
        self.model = ForceModel(system, self.dtype)
        self.loop, arrays = integrator.compiled
        #: the implicit methods have no compiled loop: ``simulate`` steps them on this view, whose
        #: evaluations are compiled (mslab.fast.newton); :meth:`advance` is for the other loops
        self.view = CompiledSystem(system, self.model) if self.loop == "implicit" else None
        self.arrays = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in arrays)
        work = system.n_particles + sum(np.size(p[0]) for p in self.model.params if p and np.ndim(p[0]))
        # (particles + the first array of each kernel: springs, anchors)
        #: steps per compiled call: about 10^7 particle+element updates (0.1 s), so Ctrl-C and the
        #: progress bar answer within a fraction of a second
        self.chunk = int(min(self.max_chunk, max(1, 10**7 // max(1, work * integrator.n_stages))))
        self._x = self._v = None
        self._mem = None
        self._kick: tuple | None = None
        #: dissipated work of the loaded state (follows the steps)
        self.dissipated = 0.0

    def load(self, state: State) -> None:
        """Take ``state`` (after the method's numpy ``start``) as the state the loop continues from."""
        self._x = _rows(state.x, self.dtype)
        self._v = _rows(state.v, self.dtype)
        self._mem = self._memory(state)
        self.dissipated = float(state.dissipated)

    def run(self, dt: float, step: int, stop: int, saved: np.ndarray, k: int, xs: np.ndarray,
            vs: np.ndarray, ds: np.ndarray, limit: float) -> tuple[int, int, bool]:
        """Take steps ``step+1 .. stop`` from the loaded state, in place; no copy of the state.

        Fills ``xs, vs, ds`` at the indices ``saved[k:]`` reached. Returns ``(step, k, ok)``;
        ``ok`` is False when step ``step`` blew up. :attr:`dissipated` follows.
        """
        out = self._run(self._x, self._v, self.dissipated, self._mem,
                        (float(dt), step, stop, saved, k, xs, vs, ds, float(limit)))
        new_step, k, self.dissipated, status, n_force = out
        self.system.counters.n_force += n_force
        return new_step, k, status == self.model.module.OK

    @property
    def x(self) -> np.ndarray:
        """The loop's positions, a float64 copy (n_particles, dim)."""
        return _particles(self._x)

    @property
    def v(self) -> np.ndarray:
        """The loop's velocities, a float64 copy (n_particles, dim)."""
        return _particles(self._v)

    def state(self) -> State:
        """Return a copy of the loop's current state, with the method's memory (float64)."""
        return State(_particles(self._x), _particles(self._v), self._memory_tuple(), self.dissipated)

    def advance(self, state: State, dt: float, step: int, stop: int, saved: np.ndarray, k: int,
                xs: np.ndarray, vs: np.ndarray, ds: np.ndarray, limit: float) -> tuple[int, int, State, bool]:
        """:meth:`run` from ``state`` at the first call (later calls continue the loaded state).

        Returns ``(step, k, state, ok)`` with a copy of the state (benchmarks/warp_cloth.py).
        """
        if self._x is None:
            self.load(state)
        new_step, k, ok = self.run(dt, step, stop, saved, k, xs, vs, ds, limit)
        return new_step, k, self.state(), ok

    def warm(self) -> None:
        """Load (or compile) the loop now, by a call of zero steps.

        The call has the argument types of ``simulate``, so the cost stays out of the run's
        wall time (``Stats.wall_time`` times the stepping, as the README's timing rule says).
        """
        if self.view is not None:
            self.view.warm()
            return
        shape = (self.system.n_particles, self.system.dim)
        x, v = np.zeros(shape[::-1], self.dtype), np.zeros(shape[::-1], self.dtype)
        empty = np.empty((0,) + shape)
        mem = self._memory(State(x.T, v.T, (), 0.0), blank=True)
        self._run(x, v, 0.0, mem, (1.0, 0, 0, np.zeros(0, dtype=np.int64), 0, empty, empty, np.empty(0), 1.0))

    def _run(self, x: np.ndarray, v: np.ndarray, dissipated: float, mem: tuple, common: tuple):
        """One call of the family's loop; ``common`` = (dt, step, stop, saved, k, xs, vs, ds, limit)."""
        mod, ig, system = self.model.module, self.integrator, self.system
        model = (self.model.cuts, self.model.w, self.model.f0, self.model.params)
        if self.loop == "explicit_rk":
            A, b = self.arrays
            return mod.run_explicit_rk(x, v, dissipated, A, b, *common, *model)
        if self.loop == "splitting":
            drift, kick = self.arrays
            mem_a, mem_p = mem
            reuse = bool(ig.fsal and not system.velocity_dependent)
            if self._kick is None:  # the kick's tableau, looked up once (a registry lookup per call)
                kick_method = ig.kick_method if system.velocity_dependent else None
                kA, kb = (kick_method.A, kick_method.b) if kick_method is not None else _EULER
                self._kick = (np.ascontiguousarray(kA), np.ascontiguousarray(kb))
            threads = jit.numba().get_num_threads()  # (the session's, set around the call)
            return mod.run_splitting(x, v, dissipated, drift, kick, reuse, *self._kick, mem_a, mem_p,
                                     *common, *model, threads)
        mem_x, mem_a, mem_p = mem
        code = mod.VERLET if self.loop == "verlet" else mod.LEAPFROG
        return mod.run_two_step(code, x, v, dissipated, mem_x, mem_a, mem_p, *common,
                                bool(system.velocity_dependent), *model)

    def _memory(self, state: State, blank: bool = False):
        """Memory arrays of the loop (coordinate-major) from the numpy ``start`` (zeros when ``blank``)."""
        shape = state.x.shape[::-1]
        if self.loop == "splitting":
            mem_a, mem_p = np.zeros(shape, self.dtype), np.zeros(1)
            if state.memory:
                mem_a.T[:], mem_p[0] = state.memory
            return mem_a, mem_p
        mem_x, mem_a, mem_p = np.zeros(shape, self.dtype), np.zeros(shape, self.dtype), np.zeros(1)
        if blank:
            return mem_x, mem_a, mem_p
        if self.loop == "verlet":
            mem_x.T[:], mem_p[0] = state.memory
        elif self.loop == "leapfrog":
            mem_x.T[:], mem_a.T[:], mem_p[0] = state.memory
        return mem_x, mem_a, mem_p

    def _memory_tuple(self) -> tuple:
        if self.loop == "explicit_rk":
            return ()
        if self.loop == "splitting":
            if not (self.integrator.fsal and not self.system.velocity_dependent):
                return ()
            mem_a, mem_p = self._mem
            return (_particles(mem_a), float(mem_p[0]))
        mem_x, mem_a, mem_p = self._mem
        mem_x, mem_a = _particles(mem_x), _particles(mem_a)
        if self.loop == "verlet":
            return (mem_x, float(mem_p[0]))
        return (mem_x, mem_a, float(mem_p[0]))


def _rows(a: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Return a new coordinate-major copy ``(dim, n)`` of ``a`` (n, dim): the loops' layout."""
    return np.array(np.asarray(a).T, dtype=dtype, order="C")


def _particles(a: np.ndarray) -> np.ndarray:
    """Return a new particle-major float64 copy ``(n_particles, dim)`` of the loop's array ``a`` (dim, n)."""
    return np.array(a.T, dtype=np.float64, order="C")
