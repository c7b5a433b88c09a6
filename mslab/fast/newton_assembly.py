"""Newton's matrix assembled by compiled loops straight into its kept pattern (the compiled path).

``A = M - c^2 K - c D`` on the free dofs (:mod:`mslab.integrators.newton.linear`). The numpy path
evaluates every effect's Jacobian as a sparse matrix and sums the terms into the kept
pattern (:class:`~mslab.integrators.newton.newton_matrix.FreePattern`, one ``np.bincount``). Here,
on the compiled path (:meth:`mslab.fast.newton.CompiledSystem.newton_assembly`, which
:class:`~mslab.integrators.newton.linear.StageSolver` asks for), the terms that dominate a cloth are
written into ``A``'s values directly:

* effects that declare undamped Hooke springs (capability ``hooke_springs``, not velocity
  dependent): one compiled pass over the springs
  (:func:`~mslab.fast.newton_kernels.spring_newton_kernel`) adds each spring's four blocks
  at precomputed positions of ``A.data``; no Jacobian matrix is built;
* linear drag (capability ``linear_drag``, ``D = -gamma I``): ``c gamma`` on the diagonal;
* constant forces (gravity): nothing;
* any other effect: its Jacobians as sparse matrices, summed into ``A`` by ``np.bincount``
  as on the numpy path.

Same matrix to round-off as the numpy assembly (``tests/test_newton_matrix.py``). Cost: one
pass over the springs and one over ``A``'s values (the row sums of the round-off floor).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.fast import newton_kernels as kernels
from mslab.integrators.newton.newton_matrix import FreePattern
from mslab.jit import compiled

if TYPE_CHECKING:
    import scipy.sparse as sp

    from mslab.effects.base import Effect
    from mslab.system import System


def _is_compiled_spring(effect: Effect) -> bool:
    return effect.hooke_springs() is not None and not effect.velocity_dependent


def _plain(effect: Effect) -> bool:
    return effect.linear_drag() is not None or effect.constant_force() is not None


class CompiledNewtonMatrix:
    """``A = M - c^2 K - c D`` on the free dofs of ``system``, assembled by compiled loops.

    Parameters
    ----------
    system : System
    c : float
    free : ndarray of bool, shape (n_dofs,)
    clamp : bool
        Drop the compressive term of every spring's block (positive definite ``A``).
    """

    def __init__(self, system: System, c: float, free: np.ndarray, clamp: bool = False):
        self.system, self.c, self.free, self.clamp = system, float(c), free, bool(clamp)
        effects = system.effects
        self.springs = [e.hooke_springs() for e in effects if _is_compiled_spring(e)]
        self.rest = [e for e in effects if not _is_compiled_spring(e) and not _plain(e)]
        gamma = sum(e.linear_drag() for e in effects if e.linear_drag() is not None)
        dim = system.dim
        self.mass_free = np.repeat(system.mass, dim)[free]
        self.inv_mass_free = 1.0 / self.mass_free
        self.base_diagonal = self.mass_free + self.c * gamma
        #: only springs and drag: A is symmetric whatever the state
        self.symmetric = not self.rest
        self.pattern: FreePattern | None = None
        self._rest_patterns: list = []
        self._row = np.empty(int(np.count_nonzero(free)))
        self._kernel = compiled(kernels.spring_newton_kernel, "the springs' Newton-matrix loop")
        self._row_sums = compiled(kernels.off_mass_row_sums, "the Newton matrix's row sums")
        self._change = compiled(kernels.relative_change, "the Newton matrix's change")

    def _rest_terms(self, x: np.ndarray, v: np.ndarray) -> tuple[list, np.ndarray]:
        """Return the other effects' terms (CSR) and their values scaled to ``c^2 K_e``, ``c D_e``."""
        stiff, damp = [], []
        for e in self.rest:
            kx, kv = getattr(e, self.system._jacobians)(x, v)  # compiled loops on the compiled view
            if kx is not None:
                stiff.append(kx.tocsr())
            if kv is not None:
                damp.append(kv.tocsr())
        c = self.c
        lin = np.concatenate([np.zeros(0)] + [p.data * (c * c) for p in stiff] + [p.data * c for p in damp])
        return stiff + damp, lin

    def _build(self, x: np.ndarray, rest_parts: list) -> None:
        """Record the pattern: the springs' blocks (their numpy Jacobians, once) and the other terms."""
        import scipy.sparse as sp

        dim, n = self.system.dim, self.system.n_particles
        spring_parts = []
        for s in self.springs:
            rows = np.concatenate([s.i, s.j, s.i, s.j])
            cols = np.concatenate([s.i, s.j, s.j, s.i])
            pairs = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
            spring_parts.append(sp.kron(pairs, np.ones((dim, dim)), format="csr"))
        offset = sum(p.nnz for p in spring_parts)
        self.pattern = FreePattern(spring_parts + rest_parts, self.free)
        self._rest_patterns = [(p.indptr.copy(), p.indices.copy()) for p in rest_parts]
        sel = self.pattern.source >= offset
        self._rest_source = self.pattern.source[sel] - offset
        self._rest_slot = self.pattern.slot[sel]
        new = np.cumsum(self.free) - 1
        m = self.pattern.size
        r = np.arange(dim)
        self._slots = []
        for s in self.springs:
            di = s.i[:, None] * dim + r  # (n_springs, dim) dofs
            dj = s.j[:, None] * dim + r
            blocks = [(di, di), (dj, dj), (di, dj), (dj, di)]
            shape = (s.i.size, dim, dim)
            rows = np.stack([np.broadcast_to(a[:, :, None], shape) for a, _ in blocks], axis=1)
            cols = np.stack([np.broadcast_to(b[:, None, :], shape) for _, b in blocks], axis=1)
            keep = self.free[rows] & self.free[cols]
            keys = new[rows].astype(np.int64) * m + new[cols]
            where = np.searchsorted(self.pattern.keys, keys)
            self._slots.append(np.where(keep, where, -1).astype(np.int64))

    def _matches(self, rest_parts: list) -> bool:
        return len(rest_parts) == len(self._rest_patterns) and all(
            np.array_equal(p.indptr, ptr) and np.array_equal(p.indices, ind)
            for p, (ptr, ind) in zip(rest_parts, self._rest_patterns, strict=True))

    def assemble(self, x: np.ndarray, v: np.ndarray) -> tuple[sp.csr_matrix, float]:
        """Return ``A`` at ``(x, v)`` on the kept pattern and ``max_i m_i^-1 sum_j |A_ij - M_ij|``.

        Counts one ``n_jac`` (the Jacobians of every effect, as ``System.jacobian_terms``).
        """
        self.system.counters.n_jac += 1
        rest_parts, lin = self._rest_terms(x, v)
        if self.pattern is None or not self._matches(rest_parts):
            self._build(x, rest_parts)
        p = self.pattern
        data = np.bincount(self._rest_slot, weights=-lin[self._rest_source], minlength=p.indices.size)
        data = data.astype(float, copy=False)
        data[p.diagonal] += self.base_diagonal
        x = np.ascontiguousarray(x, dtype=float)
        c2 = self.c * self.c
        for s, slot in zip(self.springs, self._slots, strict=True):
            self._kernel(x, s.i, s.j, s.stiffness, s.rest_length, c2, int(self.clamp), slot, data)
        row_sum = self._row_sums(p.indptr, data, p.diagonal, self.mass_free, self.inv_mass_free, self._row)
        return p.matrix(data), float(row_sum)

    def change(self, data: np.ndarray, old: np.ndarray) -> float:
        """Return ``|A - A_old|_F / |A_old|_F`` for two matrices' values on the kept pattern."""
        return float(self._change(data, old))


def hooke_energy(system: System, x: np.ndarray) -> float:
    """Return the potential energy of ``system`` with its Hooke springs' energy from a compiled loop."""
    kernel = compiled(kernels.hooke_energy_kernel, "the springs' energy loop")
    x = np.ascontiguousarray(x, dtype=float)
    total = 0.0
    for e in system.effects:
        if not e.conservative:
            continue
        s = e.hooke_springs()
        total += kernel(x, s.i, s.j, s.stiffness, s.rest_length) if s is not None else e.energy(x)
    return float(total)
