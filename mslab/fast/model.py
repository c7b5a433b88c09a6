"""The force model of the compiled path: the scene's effect kernels and their parameters."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.fast import compose

if TYPE_CHECKING:
    from mslab.effects.base import Effect
    from mslab.system import System


#: entries (particles x dimensions) from which a particle pass of the compiled loops runs on all
#: threads: about where the springs' loop does (a cloth of 160 x 160 particles; ``MIN_SPRINGS_PARALLEL``
#: in mslab.effects.spring_batches), whose launches wake the threads anyway. Below, the pass's
#: launch (tens of microseconds when the threads sleep) costs what it saves. Measured idle, two
#: threads / one: 180 x 180 cloth 1.76 with the pass in parts, 1.47 without (benchmarks/RESULTS.md)
MIN_ENTRIES_PARALLEL = 75_000
#: most parts of a particle pass (32 keep up to 32 threads busy)
MAX_PARTS = 32


def particle_cuts(size: int) -> np.ndarray:
    """Return the part boundaries of a pass over ``size`` entries (particles x dimensions).

    ``[0, size]`` (one part) below :data:`MIN_ENTRIES_PARALLEL`; else :data:`MAX_PARTS` parts
    of about equal size, each starting at a multiple of 16 entries (a cache line of float32).
    From the size alone, though the pass is elementwise: any cut gives the same bits.
    """
    if size < MIN_ENTRIES_PARALLEL:
        return np.array([0, size], dtype=np.int64)
    cuts = (np.arange(MAX_PARTS + 1, dtype=np.int64) * size // MAX_PARTS) // 16 * 16
    cuts[-1] = size
    return cuts


def kernel_reason(system: System) -> str | None:
    """Say why the effects of ``system`` cannot be compiled (None: every effect has a kernel)."""
    missing = [e.name for e in system.effects if getattr(e, "kernel", None) is None]
    if missing:
        return f"effects {missing} have no compiled kernel"
    return None


def _param(value: object, dtype: type = np.float64) -> object:
    """Return a kernel parameter as the compiled code wants it.

    Arrays become C-contiguous; integer arrays are narrowed to 32 bits where their values
    fit (half the memory traffic of a spring's indices): ``uint32`` when none is negative
    (index arrays), else ``int32``, else ``int64``. Unsigned indices spare the compiled
    code numba's test for negative indices on every access, which costs a spring loop
    10-20 % of its time (measured, ``benchmarks/RESULTS.md``); kernels use such
    values as indices only. Bools become ints; float arrays take ``dtype`` (the run's
    precision), float scalars stay Python floats.
    """
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "iu":
            if value.size == 0 or (int(value.min()) >= 0 and int(value.max()) < 2**32):
                return np.ascontiguousarray(value, dtype=np.uint32)
            small = int(value.min()) >= -(2**31) and int(value.max()) < 2**31
            return np.ascontiguousarray(value, dtype=np.int32 if small else np.int64)
        if value.dtype.kind == "b":
            return np.ascontiguousarray(value)
        return np.ascontiguousarray(value, dtype=dtype)
    if isinstance(value, bool | np.bool_):
        return int(value)
    return value


def is_constant(effect: Effect, n_particles: int, dim: int) -> bool:
    """Decide whether the effect's force is one fixed array for the whole run (gravity).

    By the effect protocol: an external force (not ``internal``) that depends on neither
    position nor velocity (both Jacobian blocks ``None``, "identically zero") and
    dissipates nothing. Internal forces (springs) are never asked: their Jacobians cost.
    """
    if effect.internal or effect.velocity_dependent or effect.dissipative:
        return False
    zeros = np.zeros((n_particles, dim))
    return effect.jacobians(zeros, zeros) == (None, None)


def plan(system: System) -> tuple[list[bool], tuple]:
    """Find which effects are constant (:func:`is_constant`) and the kernels of the others."""
    constant = [is_constant(e, system.n_particles, system.dim) for e in system.effects]
    kernels = tuple(type(e).kernel for e, c in zip(system.effects, constant, strict=True) if not c)
    return constant, kernels


class ForceModel:
    """The effects of a System as compiled kernels with their parameters.

    Constant forces (:func:`is_constant`: gravity) are summed once into ``f0`` from the
    effects' own ``force``; the loops start every force evaluation from ``f0`` (restored in
    the pass that reads the forces), so a constant effect costs no pass per step.

    Attributes
    ----------
    kernels : tuple of callable
        The ``kernel`` functions of the other effects, in the System's summation order.
    params : tuple of tuple
        Their :meth:`~mslab.effects.Effect.kernel_params`, as the kernels take them.
    f0 : ndarray, shape (dim, n_particles)
        The sum of the constant forces, coordinate-major as the loops' arrays (:mod:`mslab.fast.loops`).
    inv_mass : ndarray, shape (n_particles,)
        ``1/m`` (0 for pinned particles).
    w : ndarray, shape (dim * n_particles,)
        ``inv_mass`` tiled per coordinate (the loops' flat passes over coordinate-major arrays).
    cuts : ndarray of int64
        The parts of those passes (:func:`particle_cuts`): more than one runs them on all threads.
    module : module
        The compiled loops for these kernels (:func:`mslab.fast.compose.module_for`).
    dtype : numpy dtype
        The precision of the arrays above (float64; float32 for ``dtype="float32"`` runs): the
        constant forces and inverse masses are formed in float64 and rounded once; a constant
        force that rounds to ``-0.0`` becomes ``+0.0`` (no force entry of a loop is ``-0.0``:
        :func:`mslab.effects.spring_batches.gap_springs` relies on it).
    """

    def __init__(self, system: System, dtype: type = np.float64):
        reason = kernel_reason(system)
        if reason is not None:
            raise ValueError(reason)
        shape = (system.n_particles, system.dim)
        constant, self.kernels = plan(system)
        varying = [e for e, c in zip(system.effects, constant, strict=True) if not c]
        self.dtype = np.dtype(dtype)
        f0 = np.zeros(shape)
        for e, c in zip(system.effects, constant, strict=True):
            if c:
                f0 += e.force(np.zeros(shape), np.zeros(shape))
        self.f0 = np.ascontiguousarray(f0.T, dtype=self.dtype) + self.dtype.type(0.0)  # (-0.0 made +0.0)
        self.params = tuple(tuple(_param(p, self.dtype) for p in e.kernel_params()) for e in varying)
        self.inv_mass = np.ascontiguousarray(system.inv_mass, dtype=self.dtype)
        self.w = np.tile(self.inv_mass, system.dim)
        self.cuts = particle_cuts(self.w.size)
        kick = type(varying[-1]).kick_kernel if varying else None  # the last kernel's kick twin
        self.module = compose.module_for(self.kernels, parallel=self.cuts.size > 2, kick=kick)

    def rhs(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Return acceleration (n_particles, dim) and dissipated power: ``System.rhs`` compiled, uncounted."""
        a = np.empty(np.shape(x)[::-1])
        p = self.module.rhs(_rows(x), _rows(v), a, self.w, self.f0, self.params)
        return np.ascontiguousarray(a.T), float(p)

    def force(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Return the total force (n_particles, dim) and dissipated power from the kernels, not counted."""
        f = self.f0.copy()
        p = self.module.scene_forces(_rows(x), _rows(v), f, self.params)
        return np.ascontiguousarray(f.T), float(p)


def _rows(a: np.ndarray) -> np.ndarray:
    """Return ``a`` (n_particles, dim) as the loops' coordinate-major float64 array (dim, n_particles)."""
    return np.ascontiguousarray(np.asarray(a).T, dtype=np.float64)
