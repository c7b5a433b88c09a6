"""Hooke springs with optional damping along the spring (seed eqs. 1-2)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from mslab import fast
from mslab.effects.base import Effect


def scatter_pairs(f: np.ndarray, i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """Sum pair forces ``+f`` onto particles ``i`` and ``-f`` onto ``j`` -> (n, dim)."""
    out = np.empty((n, f.shape[1]))
    for k in range(f.shape[1]):
        out[:, k] = np.bincount(i, f[:, k], minlength=n) - np.bincount(j, f[:, k], minlength=n)
    return out


class Springs(Effect):
    """A set of Hooke springs between particle pairs.

    For the spring ``q`` joining ``i`` and ``j`` with ``d = x_i - x_j``, current length
    ``l = |d|``, unit direction ``u = d / l``, rest length ``L`` and stiffness ``k``
    (seed eq. 2), plus damping ``c`` acting on the stretch rate ``u . (v_i - v_j)``::

        f_i = k (L - l) u - c (u . (v_i - v_j)) u,      f_j = -f_i

    Energy ``U = sum_q k (l - L)^2 / 2``; dissipated power ``P = sum_q c (u . Δv)^2``.
    Jacobian blocks (``P_u = I - u u^T``)::

        df_i/dx_i = -k [ u u^T + (1 - L/l) P_u ]  -  c/l [ u (P_u Δv)^T + (u.Δv) P_u ]
        df_i/dv_i = -c u u^T

    A spring of zero current length exerts no force (``f_i = -k (d - L u)`` with ``u = 0``),
    never NaN; its Jacobian there is taken as ``-k I`` (the zero-rest-length limit).

    Parameters
    ----------
    springs : ndarray of int, shape (n_springs, 2)
    stiffness, rest_length, damping : ndarray, shape (n_springs,)
    n_particles : int
    """

    name = "springs"
    dissipative = False
    velocity_dependent = False

    def __init__(self, springs, stiffness, rest_length, damping, n_particles: int):
        self.springs = np.asarray(springs, dtype=np.int64).reshape(-1, 2)
        self.i = np.ascontiguousarray(self.springs[:, 0])
        self.j = np.ascontiguousarray(self.springs[:, 1])
        self.stiffness = np.asarray(stiffness, dtype=float)
        self.rest_length = np.asarray(rest_length, dtype=float)
        self.damping = np.asarray(damping, dtype=float)
        self.n = int(n_particles)
        damped = bool(np.any(self.damping != 0.0))
        self.velocity_dependent = damped
        self.dissipative = damped
        self.conservative = True  # the Hooke part has a potential; damping is booked as power
        self._csr = None  # Jacobian sparsity pattern, built on first use (see _assemble)

    def _geometry(self, x):
        d = x[self.i] - x[self.j]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        safe = np.where(length > 0.0, length, 1.0)
        u = np.where((length > 0.0)[:, None], d / safe[:, None], 0.0)
        return d, length, u

    def _pair_force(self, x, v):
        d, length, u = self._geometry(x)
        f = -self.stiffness[:, None] * (d - self.rest_length[:, None] * u)
        if not self.dissipative:
            return f, 0.0
        rate = np.einsum("ij,ij->i", u, v[self.i] - v[self.j])
        f -= (self.damping * rate)[:, None] * u
        return f, float(np.sum(self.damping * rate * rate))

    def force(self, x, v):
        if fast.use_numba():  # the same equations as a compiled loop (mslab/fast/kernels.py)
            return self._fast_force(x, v)[0]
        f, _ = self._pair_force(x, v)
        return scatter_pairs(f, self.i, self.j, self.n)

    def force_and_power(self, x, v):
        if fast.use_numba():
            return self._fast_force(x, v)
        f, p = self._pair_force(x, v)
        return scatter_pairs(f, self.i, self.j, self.n), p

    def _fast_force(self, x, v):
        x = np.ascontiguousarray(x, dtype=float)
        v = np.ascontiguousarray(v, dtype=float) if self.dissipative else x
        f, p = fast.compiled().spring_force(x, v, self.i, self.j, self.stiffness, self.rest_length,
                                           self.damping, self.dissipative)
        return f, float(p)

    def power(self, x, v):
        return self._pair_force(x, v)[1]

    def energy(self, x):
        _, length, _ = self._geometry(x)
        return float(0.5 * np.sum(self.stiffness * (length - self.rest_length) ** 2))

    def lengths(self, x) -> np.ndarray:
        """Current spring lengths, shape (n_springs,)."""
        return self._geometry(x)[1]

    def jacobians(self, x, v):
        d, length, u = self._geometry(x)
        dim = x.shape[1]
        eye = np.eye(dim)[None]
        uu = u[:, :, None] * u[:, None, :]
        proj = eye - uu
        ratio = np.where(length > 0.0, self.rest_length / np.where(length > 0, length, 1.0), 0.0)
        bx = -self.stiffness[:, None, None] * (uu + (1.0 - ratio)[:, None, None] * proj)
        dfdv = None
        if self.dissipative:
            dv = v[self.i] - v[self.j]
            rate = np.einsum("ij,ij->i", u, dv)
            pdv = np.einsum("kab,kb->ka", proj, dv)
            inv_l = np.where(length > 0.0, 1.0 / np.where(length > 0, length, 1.0), 0.0)
            c = (self.damping * inv_l)[:, None, None]
            bx = bx - c * (u[:, :, None] * pdv[:, None, :] + rate[:, None, None] * proj)
            dfdv = self._assemble(-self.damping[:, None, None] * uu)
        return self._assemble(bx), dfdv

    def _assemble(self, blocks: np.ndarray) -> sp.csr_matrix:
        """``mslab.effects.base.pair_blocks(blocks, i, j, n)`` into a CSR pattern computed once and reused.

        The sparsity pattern of a spring Jacobian never changes, so the sorting of a
        COO -> CSR conversion is done on the first call only: later calls sum the block
        entries into the stored slots (``np.bincount`` over a precomputed index map).
        """
        m, dim, _ = blocks.shape
        if self._csr is None or self._csr[0] != dim:
            self._csr = (dim,) + self._pattern(dim)
        _, slot, indices, indptr = self._csr
        size = self.n * dim
        b = blocks.ravel()
        data = np.bincount(slot, weights=np.concatenate([b, b, -b, -b]), minlength=indices.size)
        return sp.csr_matrix((data, indices, indptr), shape=(size, size))

    def _pattern(self, dim: int):
        """Slot of every block entry (the order of ``_assemble``'s data), CSR indices, indptr."""
        size = self.n * dim
        ri = self.i[:, None] * dim + np.arange(dim)[None, :]
        rj = self.j[:, None] * dim + np.arange(dim)[None, :]

        def grid(a, b):  # (row, col) of each entry of the blocks, in blocks.ravel() order
            return np.repeat(a, dim, axis=1).ravel(), np.tile(b, (1, dim)).ravel()

        # +B at (i, i) and (j, j), then -B at (i, j) and (j, i), as pair_blocks
        pairs = [grid(ri, ri), grid(rj, rj), grid(ri, rj), grid(rj, ri)]
        rows = np.concatenate([p[0] for p in pairs])
        cols = np.concatenate([p[1] for p in pairs])
        keys, slot = np.unique(rows * size + cols, return_inverse=True)
        indptr = np.searchsorted(keys // size, np.arange(size + 1)).astype(np.int32)
        return slot, (keys % size).astype(np.int32), indptr

    def __repr__(self):
        return f"Springs(n_springs={len(self.springs)})"
