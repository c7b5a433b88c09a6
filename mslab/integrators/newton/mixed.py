"""A float32 supernodal Cholesky factorisation of Newton's matrix: the preconditioner of CG in float64.

Newton's matrix ``A = M - c^2 K - c D`` (free dofs; :mod:`~mslab.integrators.newton.linear`) is
factored in single precision, ``P A P^T ~ L L^T`` with ``L`` float32, and used in place of a
float64 factorisation:

* a **fresh direction** solves ``A du = -M r`` by conjugate gradients in float64 preconditioned
  with ``(L L^T)^-1``: the factor's rounding (``~ kappa(A) eps_32``, eps_32 = 6e-8) leaves a
  spectrum of ``(L L^T)^-1 A`` within ``1 +- delta`` with delta ~ 1e-4 here, so each CG
  iteration gains about four decades (the direction is solved to the same relative residual
  as CG with kept factors, at most :data:`FRESH_RTOL`; 1e-12 when an exact direction is
  asked);
* a **modified Newton step** and the **CG with kept factors** of the reuse policy apply
  ``(L L^T)^-1`` once per solve, exactly where they applied the float64 factors.

Cost: the numeric factorisation does the flops of a float64 supernodal one (``sum_s (m_s -
k_s)^2 k_s`` in BLAS's ``ssyrk``, plus ``strsm`` and ``spotrf`` per supernode) at twice the
SIMD width and half the memory; a solve reads ``L`` once in each direction (``4 nnz(L)``
flops in float32: ``strsv`` and ``sgemv`` per supernode, half the time of float64 loops; its
rounding is of the order of the factor's). Measured on cloths in ``benchmarks/RESULTS.md``.

The symbolic analysis (:mod:`~mslab.integrators.newton.mixed_symbolic`: AMD order of the
particle graph, elimination tree, relaxed supernodes, the place of every entry of ``A`` in
its front) is done once per pattern and kept on the pattern. The numeric factorisation
(:mod:`~mslab.integrators.newton.mixed_kernels`) runs on one thread in a fixed order: the
same bits on every run and any thread count.

**Fallback**: when the float32 factorisation meets a pivot that is not positive (``A``
indefinite, or too close to singular for single precision) :func:`mixed_factor` returns
None, and when CG with the float32 factor does not converge within :data:`FRESH_MAX_ITER`
iterations, the caller factors in float64 as before (:class:`~mslab.integrators.newton.factor.Factor`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import numpy as np

from mslab.integrators.newton.mixed_kernels import mixed_factor_kernel, mixed_solve_kernel
from mslab.integrators.newton.mixed_symbolic import (
    children_of,
    count_kernel,
    etree_kernel,
    postorder,
    structure_kernel,
    supernodes,
)
from mslab.jit import compiled

if TYPE_CHECKING:
    import scipy.sparse as sp

    from mslab.system import Counters

#: the relative residual a fresh direction is solved to, at most (four decades: one CG iteration
#: with the float32 factor on the cloth, whose one application leaves 1e-6 to 3e-6)
FRESH_RTOL = 1e-4
#: entries of the scaled factor (``max diag = 1``) below this are stored as zeros (subnormal
#: float32 numbers are slow: :func:`~mslab.integrators.newton.mixed_kernels.mixed_factor_kernel`)
TINY = np.float32(2.0 ** -50)
#: CG iterations with a fresh float32 factor before the float64 factorisation takes over
FRESH_MAX_ITER = 8


def _blas() -> tuple:
    """Return ctypes pointers to scipy's ``spotrf``, ``strsm``, ``ssyrk``, ``strsv``, ``sgemv``."""
    import ctypes

    from numba.extending import get_cython_function_address

    global _BLAS
    if _BLAS is None:
        p = ctypes.c_void_p
        lapack, blas = "scipy.linalg.cython_lapack", "scipy.linalg.cython_blas"
        _BLAS = (ctypes.CFUNCTYPE(None, *[p] * 5)(get_cython_function_address(lapack, "spotrf")),
                 ctypes.CFUNCTYPE(None, *[p] * 11)(get_cython_function_address(blas, "strsm")),
                 ctypes.CFUNCTYPE(None, *[p] * 10)(get_cython_function_address(blas, "ssyrk")),
                 ctypes.CFUNCTYPE(None, *[p] * 8)(get_cython_function_address(blas, "strsv")),
                 ctypes.CFUNCTYPE(None, *[p] * 11)(get_cython_function_address(blas, "sgemv")))
    return _BLAS


_BLAS: Any = None
_BLAS_CONTROLLERS: list | None = None


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the body with the loaded BLAS libraries on one thread (threadpoolctl's controllers, found once).

    The factorisation and the solves call BLAS by function pointer: one thread keeps their
    order of operations, hence their bits, whatever the caller's thread count.
    """
    global _BLAS_CONTROLLERS
    if _BLAS_CONTROLLERS is None:
        from threadpoolctl import ThreadpoolController

        _BLAS_CONTROLLERS = [c for c in ThreadpoolController().lib_controllers if c.user_api == "blas"]
    before = [ctl.get_num_threads() for ctl in _BLAS_CONTROLLERS]
    for ctl, count in zip(_BLAS_CONTROLLERS, before, strict=True):
        if count != 1:
            ctl.set_num_threads(1)
    try:
        yield
    finally:
        for ctl, count in zip(_BLAS_CONTROLLERS, before, strict=True):
            if count != 1:
                ctl.set_num_threads(count)


def block_size(indptr: np.ndarray, indices: np.ndarray, n: int, dim: int) -> int:
    """Return ``dim`` when the pattern is made of whole ``dim x dim`` blocks' rows, else 1."""
    return dim if dim > 1 and n % dim == 0 else 1


class MixedAnalysis:
    """The symbolic analysis of one pattern (CSR ``indptr, indices``, ``n`` dofs, ``d`` per particle).

    Attributes: ``perm`` (new -> old dof), ``sn`` (per supernode: first column, ``k``, ``m``,
    start in ``L``, start in ``rows``/``rel``), ``rows`` (each supernode's rows below its
    columns), ``rel`` (their places in the parent's front), ``children``/``child_ptr``,
    ``a_ptr``/``a_slot``/``a_pos`` (the entries of ``A`` per front), ``l_size``, ``front_size``,
    ``stack_size``, ``flops`` (of the numeric factorisation).
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray, n: int, d: int):
        import scipy.sparse as sp

        start = time.perf_counter()
        nodes = n // d
        r = np.repeat(np.arange(n), np.diff(indptr)) // d
        c = np.asarray(indices, dtype=np.int64) // d
        graph = sp.csr_matrix((np.ones(r.size), (r, c)), shape=(nodes, nodes))
        graph = (graph + graph.T).tocsr()
        graph.setdiag(0)
        graph.eliminate_zeros()
        order = amd_order(graph)
        parent = self._etree(graph, order)
        order = order[postorder(parent)]
        g = graph[order][:, order].tocsr()
        g.sort_indices()
        gp, gi = g.indptr.astype(np.int64), g.indices.astype(np.int64)
        parent = self._etree(graph, order)
        mark, count = np.empty(nodes, np.int64), np.empty(nodes, np.int64)
        compiled(count_kernel, "the column counts of the float32 factor")(gp, gi, parent, mark, count)
        sptr = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
        sidx = np.empty(int(sptr[-1]), np.int64)
        child_ptr, children = children_of(parent)
        compiled(structure_kernel, "the structure of the float32 factor")(
            gp, gi, parent, child_ptr, children, sptr, sidx, mark)
        self._supernodes(parent, count, sptr, sidx, supernodes(parent, count, d), d, nodes)
        self.perm = (order[:, None] * d + np.arange(d)).ravel().astype(np.int64)
        self._entries(indptr, indices, n)
        self.scratch: tuple | None = None  # (front, stack) of the numeric factorisation, made on first use
        self.seconds = time.perf_counter() - start

    @staticmethod
    def _etree(graph: sp.csr_matrix, order: np.ndarray) -> np.ndarray:
        g = graph[order][:, order].tocsr()
        g.sort_indices()
        parent, ancestor = np.empty(g.shape[0], np.int64), np.empty(g.shape[0], np.int64)
        compiled(etree_kernel, "the elimination tree")(g.indptr.astype(np.int64), g.indices.astype(np.int64),
                                                      parent, ancestor)
        return parent

    def _supernodes(self, parent: np.ndarray, count: np.ndarray, sptr: np.ndarray, sidx: np.ndarray,
                    first: np.ndarray, d: int, nodes: int) -> None:
        """Expand the particle-level supernodes to dofs: ``sn``, ``rows``, ``rel``, children, sizes."""
        last = np.append(first[1:], nodes) - 1
        of = np.repeat(np.arange(first.size), np.diff(np.append(first, nodes)))
        below = [(sidx[sptr[lst]:sptr[lst + 1]][:, None] * d + np.arange(d)).ravel() for lst in last]
        k = (last - first + 1) * d
        m = k + np.array([b.size for b in below], dtype=np.int64)
        sparent = np.where(parent[last] >= 0, of[np.maximum(parent[last], 0)], -1)
        self.child_ptr, self.children = children_of(sparent)
        lstart = np.concatenate([[0], np.cumsum(m * k)])
        rstart = np.concatenate([[0], np.cumsum(m - k)])
        self.sn = np.column_stack([first * d, k, m, lstart[:-1], rstart[:-1]]).astype(np.int64)
        self.rows = np.concatenate(below + [np.zeros(0, np.int64)]).astype(np.int64)
        rel = []
        for s, rows in enumerate(below):
            p = sparent[s]
            if p < 0:
                rel.append(np.zeros(rows.size, np.int64))
                continue
            own = rows - first[p] * d
            beyond = k[p] + np.searchsorted(below[p], rows)
            rel.append(np.where(rows < first[p] * d + k[p], own, beyond))
        self.rel = np.concatenate(rel + [np.zeros(0, np.int64)]).astype(np.int64)
        self.l_size = int(lstart[-1])
        self.front_size = int((m * m).max()) if m.size else 0
        top, high = 0, 0
        for s in range(first.size):  # the update stack in the factorisation's order
            kids = self.children[self.child_ptr[s]:self.child_ptr[s + 1]]
            top -= int(np.sum((m[kids] - k[kids]) ** 2))
            top += int((m[s] - k[s]) ** 2)
            high = max(high, top)
        self.stack_size = high
        self.flops = float(np.sum((m - k) ** 2 * k + (m - k) * k * k + k ** 3 / 3.0))
        self._of_dof = np.repeat(np.arange(first.size), k)
        self._below = below

    def _entries(self, indptr: np.ndarray, indices: np.ndarray, n: int) -> None:
        """Find the place of every lower entry of ``P A P^T`` in its supernode's front."""
        iperm = np.empty(n, np.int64)
        iperm[self.perm] = np.arange(n)
        slots = np.arange(indptr[-1], dtype=np.int64)
        r = iperm[np.repeat(np.arange(n), np.diff(indptr))]
        c = iperm[np.asarray(indices, dtype=np.int64)]
        low = r >= c
        slots, r, c = slots[low], r[low], c[low]
        s = self._of_dof[c]
        first, k, m = self.sn[s, 0], self.sn[s, 1], self.sn[s, 2]
        keys = np.concatenate([si * n + b for si, b in enumerate(self._below)] + [np.zeros(0, np.int64)])
        place = np.where(r < first + k, r - first, k + np.searchsorted(keys, s * n + r) - self.sn[s, 4])
        pos = place + (c - first) * m
        order = np.argsort(s, kind="stable")
        self.a_slot, self.a_pos = slots[order], pos[order].astype(np.int64)
        per = np.bincount(s, minlength=self.sn.shape[0])
        self.a_ptr = np.concatenate([[0], np.cumsum(per)]).astype(np.int64)
        del self._below, self._of_dof


def amd_order(graph: sp.csr_matrix) -> np.ndarray:
    """Return the approximate minimum degree order of a symmetric graph (CHOLMOD's AMD, cvxopt)."""
    import cvxopt
    import cvxopt.amd
    import scipy.sparse as sp

    n = graph.shape[0]
    low = sp.tril(graph + sp.identity(n), format="coo")
    M = cvxopt.spmatrix(1.0, low.row.astype(np.int64), low.col.astype(np.int64), (n, n))
    return np.asarray(cvxopt.amd.order(M, uplo="L"), dtype=np.int64).ravel()


class MixedFactor:
    """``P A P^T ~ L L^T`` in float32 (module docstring); ``solve(b)`` applies ``(L L^T)^-1`` in float64.

    Build with :func:`mixed_factor`. Attributes as :class:`~mslab.integrators.newton.factor.Factor`:
    ``A``, ``pattern``, ``kind`` (``"mixed32"``), ``definite``, ``seconds``, ``solve_seconds``.
    """

    kind = "mixed32"
    definite = True
    n_negative = 0
    solve_seconds: float = 0.0

    def __init__(self, A: sp.csr_matrix, analysis: MixedAnalysis, L: np.ndarray, pattern: Any, scale: float):
        self.A, self.analysis, self.L, self.pattern, self.scale = A, analysis, L, pattern, scale
        self._work = np.empty(2 * analysis.perm.size, np.float32)
        self._kernel = compiled(mixed_solve_kernel, "the solves with the float32 factor")

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Return ``P^T (L L^T)^-1 P b`` (float32 BLAS on ``b`` scaled by a power of two; timed)."""
        start = time.perf_counter()
        a = self.analysis
        out = np.empty(a.perm.size)
        rhs = np.ascontiguousarray(b, dtype=float)
        top = float(np.max(np.abs(rhs))) if rhs.size else 0.0
        if not 0.0 < top < np.inf:  # zero (the answer) or not finite (NaN reaches CG, which stops)
            out[:] = rhs * self.scale
            self.solve_seconds = time.perf_counter() - start
            return out
        shift = float(2.0 ** np.frexp(top)[1])  # max |b / shift| in [1/2, 1): exact
        ints, reals, chars = np.zeros(4, np.int32), np.zeros(3, np.float32), np.zeros(3, np.uint8)
        with one_blas_thread():
            self._kernel(rhs, shift, a.perm, a.sn, a.rows, self.L, self._work, out, *_blas()[3:], ints, reals,
                         chars)
        out *= self.scale
        self.solve_seconds = time.perf_counter() - start
        return out


def analysis_of(pattern: Any, A: sp.csr_matrix, dim: int) -> MixedAnalysis:
    """Return the kept analysis of ``pattern`` (made on first use; a pattern-less ``A``: its own)."""
    kept = getattr(pattern, "mixed", None) if pattern is not None else None
    if kept is None:
        n = A.shape[0]
        kept = MixedAnalysis(A.indptr, A.indices, n, block_size(A.indptr, A.indices, n, dim))
        if pattern is not None:
            pattern.mixed = kept
    return kept


def mixed_factor(A: sp.csr_matrix, counters: Counters, pattern: Any = None,
                 dim: int = 1) -> MixedFactor | None:
    """Factor the symmetric ``A`` (CSR, its kept ``pattern``) in float32; None if a pivot is not positive.

    Counted in ``n_factor``. ``dim``: dofs per particle (the blocks of the analysis).
    """
    start = time.perf_counter()
    counters.n_factor += 1
    a = analysis_of(pattern, A, dim)
    L = np.empty(a.l_size, np.float32)
    if a.scratch is None:  # the front and the update stack: work space kept with the analysis
        a.scratch = (np.empty(max(a.front_size, 1), np.float32), np.empty(max(a.stack_size, 1), np.float32))
    front, stack = a.scratch
    kernel = compiled(mixed_factor_kernel, "the float32 supernodal factorisation")
    top = float(np.max(A.diagonal())) if A.shape[0] else 1.0
    if not top > 0.0:
        return None
    scale = 1.0 / top
    ints, reals, chars = np.zeros(8, np.int32), np.zeros(2, np.float32), np.zeros(8, np.uint8)
    with one_blas_thread():
        info = kernel(np.asarray(A.data, dtype=float), scale, TINY, a.a_ptr, a.a_slot, a.a_pos, a.sn,
                      a.children, a.child_ptr, a.rel, L, front, stack, *_blas()[:3], ints, reals, chars)
    if info != 0:  # (LAPACK stops at a pivot that is not positive or is NaN)
        return None
    factor = MixedFactor(A, a, L, pattern, scale)
    factor.seconds = time.perf_counter() - start
    return factor
