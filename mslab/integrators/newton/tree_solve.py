"""Solves with one kept sparse ``L D L^T`` factorisation on every core: the elimination tree split.

A method that solves with the *same* matrix many times (the fast mass-spring method's global
step, :mod:`mslab.integrators.families.local_global`: ten solves per frame, one matrix per
scene and dt) spends most of its time in the triangular solves. CHOLMOD (through cvxopt)
solves on one core and holds Python's lock. :class:`TreeSolve` keeps CHOLMOD's
factorisation ``P A P^T = L D L^T`` (simplicial, unit lower ``L``, fill-reducing ``P``)
and solves with it in compiled loops that share the work among threads:

* **forward** ``L y = P b``: row ``r`` of ``L`` touches only the rows of its descendants in
  the *elimination tree* (``parent(c)`` = the first row below the diagonal in column ``c``).
  Subtrees are independent: they are dealt to threads (largest first, until the threads'
  work is balanced within :data:`BALANCE`), each thread sweeping its columns in increasing
  order and subtracting ``L[r, c] y[c]`` from the rows of its own subtrees; the *top* of the
  tree (the nodes in no dealt subtree: the last separators) follows on one thread, row by
  row, subtracting in increasing column order.
* ``z = D^-1 y``, then **backward** ``L^T x = z``: column ``c`` reads only its ancestors, so
  the top goes first, then the subtrees on their threads, each column in decreasing order.

Every ``y[r]`` receives the same subtractions in the same order (increasing column) as in
a plain one-thread sweep, whatever the split and the number of threads: **the result is
bitwise the same on any thread count** (``tests/test_tree_solve.py``). Cost: ``4 nnz(L)``
flops per right-hand side column, the top's share on one thread (on the 81 x 81 cloth about
a quarter of the work); memory ``12 nnz(L)`` bytes (one copy of ``L``, 32-bit row indices).

The factorisation is CHOLMOD's, ordered by METIS's nested dissection (:func:`nested_dissection`;
CHOLMOD's AMD without pymetis), factored once; ``ArithmeticError`` is
not caught here: a matrix that is not positive definite makes :func:`tree_factor` return
None and the caller keeps its usual :class:`~mslab.integrators.newton.linear.Factor`.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.newton.tree_kernels import tree_solve_kernel
from mslab.jit import compiled, thread_count

if TYPE_CHECKING:
    import scipy.sparse as sp

    from mslab.system import Counters

#: subtrees are dealt until the busiest thread has at most this much more than its share
BALANCE = 1.03
#: below this many entries in L a solve runs on one thread (a parallel launch costs more)
MIN_PARALLEL_ENTRIES = 50_000


def cholmod_ldlt(A: sp.spmatrix) -> tuple[np.ndarray, sp.csc_matrix] | None:
    """Return CHOLMOD's ``(perm, L)`` with ``A[perm][:, perm] = L D L^T`` (D on L's diagonal).

    None when cvxopt is missing or ``A`` is not positive definite (a pivot of ``D`` not
    positive: by Sylvester's law of inertia the signs of ``D`` are those of ``A``'s
    eigenvalues). The factorisation is simplicial (``getfactor`` exports only those);
    ``perm`` is read by applying CHOLMOD's permutation to ``0 .. n-1``.
    """
    import scipy.sparse as sp

    from mslab.integrators.newton.newton_matrix import cholmod_module

    cvxopt = cholmod_module()
    if cvxopt is None:
        return None
    lower = sp.tril(A, format="coo")
    n = A.shape[0]
    M = cvxopt.spmatrix(lower.data.astype(float), lower.row.astype(np.int64), lower.col.astype(np.int64),
                        (n, n))
    options = cvxopt.cholmod.options
    before = options.get("supernodal")
    options["supernodal"] = 0  # simplicial: L D L^T, exportable
    try:
        order = nested_dissection(A)
        if order is None:
            F = cvxopt.cholmod.symbolic(M, uplo="L")
        else:
            F = cvxopt.cholmod.symbolic(M, uplo="L", p=cvxopt.matrix(order.astype(int)))
        cvxopt.cholmod.numeric(M, F)
    except ArithmeticError:
        return None
    finally:
        if before is None:
            del options["supernodal"]
        else:
            options["supernodal"] = before
    probe = cvxopt.matrix(np.arange(n, dtype=float))
    cvxopt.cholmod.solve(F, probe, sys=7)  # probe = P (0, 1, ..., n-1)
    perm = np.rint(np.array(probe).ravel()).astype(np.int64)
    Lc = cvxopt.cholmod.getfactor(F)
    L = sp.csc_matrix((np.array(Lc.V).ravel(), (np.array(Lc.I).ravel(), np.array(Lc.J).ravel())),
                      shape=(n, n))
    L.sort_indices()
    pivots = L.diagonal()
    if not np.all(pivots > 0.0) or not np.all(np.isfinite(L.data)):
        return None  # L D L^T exists for some indefinite matrices too: positive pivots = definite
    return perm, L


def nested_dissection(A: sp.spmatrix) -> np.ndarray | None:
    """Return METIS's nested dissection ordering of ``A``'s graph (pymetis), or None without pymetis.

    Nested dissection numbers a small separator of the mesh last and orders the two halves
    it separates the same way: the elimination tree splits into independent subtrees near
    its root, and the serial top is only the last separators. On the 81 x 81 cloth's global
    matrix: 13 % of the solve's work in the top and ``nnz(L)`` 397k, against 23 % and 420k
    with CHOLMOD's own AMD (which is used without pymetis).
    """
    import scipy.sparse as sp

    try:
        import pymetis
    except ImportError:
        return None
    graph = sp.csr_matrix(A, copy=True)
    graph.setdiag(0)
    graph.eliminate_zeros()
    graph.sort_indices()
    if graph.shape[0] < 2 or graph.nnz == 0:
        return None
    order, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(graph.indptr, graph.indices))
    return np.asarray(order, dtype=np.int64)


def deal_subtrees(parent: np.ndarray, work: np.ndarray, bins: int) -> np.ndarray:
    """Return each node's thread (0..bins-1), or -1 for the top of the elimination tree.

    Subtrees are dealt largest first to the least busy thread; while the busiest has more
    than :data:`BALANCE` times its share, the largest subtree is split (its root joins the
    top, its children's subtrees are dealt instead).
    """
    n = parent.size
    below = work.astype(float).copy()  # work of each node's subtree (children come first)
    for c in range(n):
        if parent[c] >= 0:
            below[parent[c]] += below[c]
    children: list[list[int]] = [[] for _ in range(n)]
    for c in range(n):
        if parent[c] >= 0:
            children[parent[c]].append(c)
    roots = [c for c in range(n) if parent[c] < 0]
    owner = np.full(n, -1, dtype=np.int64)
    while True:
        roots.sort(key=lambda c: (-below[c], c))  # ties by node number: the same deal everywhere
        load = np.zeros(bins)
        dealt = []
        for c in roots:
            t = int(np.argmin(load))
            load[t] += below[c]
            dealt.append(t)
        if not roots or load.max() <= BALANCE * load.sum() / bins or bins == 1:
            break
        roots = roots[1:] + children[roots[0]]
    for c, t in zip(roots, dealt, strict=True):
        stack = [c]
        while stack:
            node = stack.pop()
            owner[node] = t
            stack.extend(children[node])
    return owner


class TreeSolve:
    """``A^-1 b`` with CHOLMOD's ``L D L^T`` of ``A``, the triangular solves on every core (module docstring).

    Build with :func:`tree_factor`. ``solve(b)`` takes ``b`` of shape (n,) or (n, k) and
    returns ``x`` of the same shape; ``seconds`` is the factorisation's wall time,
    ``solve_seconds`` the last solve's (as :class:`~mslab.integrators.newton.linear.Factor`).
    """

    kind = "cholmod_tree"
    definite = True
    n_negative = 0
    solve_seconds: float = 0.0

    def __init__(self, A: sp.spmatrix, perm: np.ndarray, L: sp.csc_matrix, bins: int):
        import scipy.sparse as sp

        n = A.shape[0]
        self.A, self.perm = A, perm
        self.diagonal = L.diagonal().copy()
        strict = sp.tril(L, -1, format="csc")
        strict.sort_indices()
        self.indptr = strict.indptr.astype(np.int64)
        self.indices = strict.indices.astype(np.int32)
        self.data = strict.data.astype(float)
        parent = np.full(n, -1, dtype=np.int64)  # the elimination tree
        has = np.diff(self.indptr) > 0
        parent[has] = self.indices[self.indptr[:-1][has]]
        rows = strict.tocsr()
        work = np.diff(self.indptr) + np.diff(rows.indptr) + 1
        bins = bins if strict.nnz >= MIN_PARALLEL_ENTRIES else 1
        self.owner = deal_subtrees(parent, work, bins)
        self.bins = bins
        lists = [np.flatnonzero(self.owner == t) for t in range(bins)]
        self.nodes = np.concatenate(lists).astype(np.int64) if n else np.zeros(0, np.int64)
        self.offsets = np.concatenate([[0], np.cumsum([len(c) for c in lists])]).astype(np.int64)
        self.top = np.flatnonzero(self.owner < 0).astype(np.int64)
        # each column's entries in rows of its own thread come first (the top's rows are the
        # ancestors above a subtree: larger numbers); the rest reach the top by its rows
        col_owner = np.repeat(self.owner, np.diff(self.indptr))
        own = self.owner[self.indices] == col_owner
        counted = np.concatenate([[0], np.cumsum(own)])
        self.inner_end = self.indptr[:-1] + counted[self.indptr[1:]] - counted[self.indptr[:-1]]
        top_rows = rows[self.top]
        top_rows.sort_indices()
        self.top_ptr = top_rows.indptr.astype(np.int64)
        self.top_cols = top_rows.indices.astype(np.int32)
        self.top_vals = top_rows.data.astype(float)
        self._kernel = compiled(tree_solve_kernel, "the triangular solves of the kept factorisation")

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` (timed)."""
        start = time.perf_counter()
        rhs = np.asarray(b, dtype=float)
        cols = rhs.reshape(rhs.shape[0], -1)
        n, k = cols.shape
        x = np.empty((n, k))
        work = np.empty((n, 3))
        out = np.empty((n, 3))
        for first in range(0, k, 3):  # three columns at a time, the last block padded with zeros
            block = cols[:, first:first + 3]
            if block.shape[1] < 3:
                block = np.concatenate([block, np.zeros((n, 3 - block.shape[1]))], axis=1)
            self._kernel(self.perm, self.indptr, self.indices, self.data, self.inner_end, self.diagonal,
                         self.nodes, self.offsets, self.top, self.top_ptr, self.top_cols, self.top_vals,
                         block, work, out)
            x[:, first:first + 3] = out[:, :min(3, k - first)]
        self.solve_seconds = time.perf_counter() - start
        return x.reshape(rhs.shape)


def tree_factor(A: sp.spmatrix, counters: Counters, threads: int | None = None) -> TreeSolve | None:
    """Factor the symmetric positive definite ``A`` for :class:`TreeSolve` (counted in ``n_factor``).

    ``threads``: the threads the solves are split for (None: ``$MSLAB_THREADS``, else every
    thread numba has). None when cvxopt is missing or ``A`` is not positive definite.
    """
    from mslab.jit import numba

    start = time.perf_counter()
    factored = cholmod_ldlt(A)
    if factored is None:
        return None
    counters.n_factor += 1
    bins = thread_count(threads) or numba().get_num_threads()
    tree = TreeSolve(A, *factored, bins=max(1, int(bins)))
    tree.seconds = time.perf_counter() - start
    return tree
