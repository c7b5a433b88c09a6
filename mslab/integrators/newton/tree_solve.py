"""Solves with one kept sparse ``L D L^T`` factorisation on every core: the elimination tree split.

A method that solves with the *same* matrix many times (the fast mass-spring method's global
step, :mod:`mslab.integrators.families.local_global`: ten solves per frame, one matrix per
scene and dt) spends most of its time in the triangular solves. CHOLMOD (through cvxopt)
solves on one core and holds Python's lock. :class:`TreeSolve` keeps CHOLMOD's
factorisation ``P A P^T = L D L^T`` (simplicial, unit lower ``L``; ``P`` METIS's nested
dissection) and solves with it in compiled loops (:mod:`~mslab.integrators.newton.tree_kernels`)
that share the work among threads:

* **supernodes** (:class:`Supernodes`): runs of columns with the same rows below them (the
  separators of nested dissection) are stored as dense blocks; a row's sum over a block's
  columns is kept in registers, four rows at a time, one store per row instead of one per
  entry. Narrow runs stay columns.
* **forward** ``L y = P b``: row ``r`` of ``L`` touches only the rows of its descendants in
  the *elimination tree* (``parent(c)`` = the first row below the diagonal in column ``c``).
  Subtrees are independent: whole supernodes' subtrees are dealt to threads (largest
  first, until the threads' work is balanced within :data:`BALANCE`), each thread sweeping
  its supernodes in increasing order; the *top* of the tree (the last separators) follows
  on one thread, pulling the sums the threads left for its rows.
* ``z = D^-1 y``, then **backward** ``L^T x = z``: a column reads only its ancestors, so the
  top goes first, then the subtrees on their threads, supernodes in decreasing order.

Every ``y[r]`` is ``b[r]`` minus each supernode's sum for row ``r``, in increasing supernode
order, whoever computes it (``tests/test_tree_solve.py`` restates the order in plain Python):
**the result is bitwise the same on any thread count and split**. Cost: ``4 nnz(L)`` flops
per right-hand side column, the top's share on one thread (on the 81 x 81 cloth's global
matrix 13 % of the work); memory about ``8 nnz(L)`` bytes.

The factorisation is CHOLMOD's (:func:`cholmod_ldlt`), ordered by METIS's nested dissection
(:func:`nested_dissection`; CHOLMOD's AMD without pymetis), factored once; a matrix that is
not positive definite makes :func:`tree_factor` return None and the caller keeps its usual
:class:`~mslab.integrators.newton.linear.Factor`.
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
#: supernodes narrower than this are solved column by column (a row of a dense block pays a
#: set-up that only four or more columns repay: measured on the 81 x 81 cloth's factor)
MIN_WIDTH = 4


def cholmod_ldlt(A: sp.spmatrix) -> tuple[np.ndarray, sp.csc_matrix] | None:
    """Return CHOLMOD's ``(perm, L)`` with ``A[perm][:, perm] = L D L^T`` (``D`` on ``L``'s diagonal).

    None when cvxopt is missing, ``A`` is empty or not positive definite (CHOLMOD's ``L
    L^T`` stops at a pivot that is not positive; an ``L D L^T`` with a pivot of ``D`` that
    is not positive is refused here: by Sylvester's law of inertia the signs of ``D`` are
    those of ``A``'s eigenvalues). CHOLMOD chooses its factorisation (supernodal ``L L^T``
    for the large matrices: 9x faster than simplicial at 200 x 200 particles); ``getfactor``
    exports it, an ``L L^T`` (told apart by a product with a random vector) is written as
    ``L D L^T`` (``D = diag(L)^2``, columns divided by their diagonal); the explicit zeros of
    CHOLMOD's supernodes are kept (they make wider blocks). ``perm`` is read by applying
    CHOLMOD's permutation to ``0 .. n-1``.
    """
    import scipy.sparse as sp

    from mslab.integrators.newton.newton_matrix import cholmod_module

    cvxopt = cholmod_module()
    n = A.shape[0]
    if cvxopt is None or n == 0:
        return None
    lower = sp.tril(A, format="coo")
    M = cvxopt.spmatrix(lower.data.astype(float), lower.row.astype(np.int64), lower.col.astype(np.int64),
                        (n, n))
    order = nested_dissection(A)
    try:
        if order is None:
            F = cvxopt.cholmod.symbolic(M, uplo="L")
        else:
            F = cvxopt.cholmod.symbolic(M, uplo="L", p=cvxopt.matrix(order.astype(int)))
        cvxopt.cholmod.numeric(M, F)
    except (ArithmeticError, ValueError):
        return None
    probe = cvxopt.matrix(np.arange(n, dtype=float))
    cvxopt.cholmod.solve(F, probe, sys=7)  # probe = P (0, 1, ..., n-1)
    perm = np.rint(np.array(probe).ravel()).astype(np.int64)
    Lc = cvxopt.cholmod.getfactor(F)
    L = sp.csc_matrix((np.array(Lc.V).ravel(), (np.array(Lc.I).ravel(), np.array(Lc.J).ravel())),
                      shape=(n, n))
    L.sort_indices()
    pivots = L.diagonal()
    if not np.all(pivots > 0.0) or not np.all(np.isfinite(L.data)):
        return None  # a pivot that is not positive: not positive definite
    z = np.random.default_rng(0).standard_normal(n)
    target = A[perm][:, perm] @ z
    as_ll = np.abs(L @ (L.T @ z) - target).max()
    unit = L - sp.diags(pivots) + sp.identity(n)
    as_ldl = np.abs(unit @ (pivots * (unit.T @ z)) - target).max()
    if as_ll < as_ldl:  # L L^T: D = diag(L)^2 and L's columns divided by their diagonal
        L = L @ sp.diags(1.0 / pivots)
        L.setdiag(pivots * pivots)
        L.sort_indices()
    return perm, sp.csc_matrix(L)


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
        indptr, indices = strict.indptr.astype(np.int64), strict.indices.astype(np.int64)
        parent = np.full(n, -1, dtype=np.int64)  # the elimination tree
        has = np.diff(indptr) > 0
        parent[has] = indices[indptr[:-1][has]]
        table = Supernodes(indptr, indices, strict.data, parent)
        self.supernodes = table
        bins = bins if strict.nnz >= MIN_PARALLEL_ENTRIES else 1
        self.sowner = deal_subtrees(table.parent, table.work, bins)  # each supernode's thread, -1: top
        self.owner = np.repeat(self.sowner, table.sn[:, 1])  # each node's
        self.bins = bins
        lists = [np.flatnonzero(self.sowner == t) for t in range(bins)]
        self.sn_order = np.concatenate(lists).astype(np.int64)
        self.sn_offsets = np.concatenate([[0], np.cumsum([len(c) for c in lists])]).astype(np.int64)
        self.top_sn = np.flatnonzero(self.sowner < 0).astype(np.int64)
        node_lists = [np.flatnonzero(self.owner == t) for t in range(bins)]
        self.nodes = np.concatenate(node_lists).astype(np.int64) if n else np.zeros(0, np.int64)
        self.offsets = np.concatenate([[0], np.cumsum([len(c) for c in node_lists])]).astype(np.int64)
        self.top = np.flatnonzero(self.owner < 0).astype(np.int64)
        self.cptr, self.contrib = table.inner_and_top(self.sowner, self.owner)
        self.buffer = np.zeros((table.rows.size, 3))
        self._kernel = compiled(tree_solve_kernel, "the triangular solves of the kept factorisation")

    def kernel_args(self) -> tuple:
        """Return the arrays of the compiled solves (``tree_kernels.tree_solve_kernel``'s order)."""
        t = self.supernodes
        return (t.sn, t.rows, t.blk, t.tri, self.diagonal, self.sowner, self.sn_order, self.sn_offsets,
                self.top_sn, self.cptr, self.contrib, self.buffer, t.widest)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` (timed)."""
        start = time.perf_counter()
        if np.iscomplexobj(b):
            raise TypeError("TreeSolve.solve: a real right-hand side is expected, got complex values")
        rhs = np.asarray(b, dtype=float)
        if rhs.ndim not in (1, 2) or rhs.shape[0] != self.perm.size:
            raise ValueError(f"TreeSolve.solve: b must have {self.perm.size} rows (shape (n,) or (n, k)), "
                             f"got shape {rhs.shape}")
        cols = rhs.reshape(rhs.shape[0], -1)
        n, k = cols.shape
        x = np.empty((n, k))
        work = np.empty((n, 3))
        out = np.empty((n, 3))
        for first in range(0, k, 3):  # three columns at a time, the last block padded with zeros
            block = cols[:, first:first + 3]
            if block.shape[1] < 3:
                block = np.concatenate([block, np.zeros((n, 3 - block.shape[1]))], axis=1)
            self._kernel(self.perm, *self.kernel_args(), block, work, out)
            x[:, first:first + 3] = out[:, :min(3, k - first)]
        self.solve_seconds = time.perf_counter() - start
        return x.reshape(rhs.shape)


class Supernodes:
    """The strict lower part of ``L`` by supernodes: runs of columns ``c .. c+w-1`` with nested structure.

    Column ``c+m``'s rows below the diagonal are ``c+m+1 .. c+w-1`` (the supernode's
    triangle) and then the same rows ``R`` for every column (``parent(c+m) = c+m+1``:
    fundamental supernodes; those narrower than :data:`MIN_WIDTH` are cut into columns).
    Stored dense: ``tri`` (``w x w`` row-major, the strict lower triangle ``L[c+a, c+b]``,
    ``a > b``) and ``blk`` (``|R| x w`` row-major, ``L[R[i], c+m]``): the solves read them
    in order and sum over a row's ``w`` columns in registers.

    ``sn[k]`` = (first column, width, start in ``rows``, start in ``blk``, start in ``tri``,
    rows of its own thread (set by :meth:`inner_and_top`), ``|R|``); ``parent`` the tree of
    supernodes, ``work`` each one's entries (for the deal), ``widest`` the largest width.
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, parent: np.ndarray):
        n = parent.size
        count = np.diff(indptr)
        joins = np.zeros(n, dtype=bool)  # column c continues the supernode of c - 1
        joins[1:] = (parent[:-1] == np.arange(1, n)) & (count[1:] == count[:-1] - 1)
        run = np.cumsum(~joins) - 1  # narrow runs are cut into columns: the sweep of one column is faster
        joins &= np.bincount(run)[run] >= MIN_WIDTH
        first = np.flatnonzero(~joins)
        width = np.diff(np.append(first, n))
        of_column = np.repeat(np.arange(first.size), width)
        below = count[first] - (width - 1)
        rows_at = np.concatenate([[0], np.cumsum(below)])
        blk_at = np.concatenate([[0], np.cumsum(below * width)])
        tri_at = np.concatenate([[0], np.cumsum(width * width)])
        self.sn = np.column_stack([first, width, rows_at[:-1], blk_at[:-1], tri_at[:-1], below, below])
        self.sn = self.sn.astype(np.int64)
        self.widest = int(width.max()) if n else 1
        # every entry of the strict lower part: its supernode k, column offset m and place e in its column
        k = np.repeat(of_column, count)
        m = np.repeat(np.arange(n) - first[of_column], count)
        e = np.arange(indptr[-1]) - np.repeat(indptr[:-1], count)
        w = width[k]
        in_tri = e < w - 1 - m
        self.tri = np.zeros(int(tri_at[-1]))
        a = m + 1 + e  # the triangle's row (relative to the supernode's first column)
        self.tri[(tri_at[k] + a * w + m)[in_tri]] = data[in_tri]
        i = e - (w - 1 - m)  # the row's place in R
        self.blk = np.zeros(int(blk_at[-1]))
        self.blk[(blk_at[k] + i * w + m)[~in_tri]] = data[~in_tri]
        from_first = ~in_tri & (m == 0)
        self.rows = np.zeros(int(rows_at[-1]), dtype=np.int64)
        self.rows[(rows_at[k] + i)[from_first]] = indices[from_first]
        last = first + width - 1
        self.parent = np.where(parent[last] >= 0, of_column[np.maximum(parent[last], 0)], -1)
        self.work = (count[first] * width + width).astype(float)

    def inner_and_top(self, sowner: np.ndarray, owner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Set each supernode's rows of its own thread; return the top rows' contributions (CSR).

        A thread's supernode updates the rows of its thread directly (they come first in
        ``R``: a subtree's nodes are numbered below the top above it) and leaves its sums for
        the top's rows in the buffer. Returns ``cptr`` (per row) and ``contrib`` (supernode,
        place in its ``R``): for each top row, every supernode whose ``R`` holds it, increasing.
        """
        sn, rows = self.sn, self.rows
        k = np.repeat(np.arange(sn.shape[0]), sn[:, 6])
        place = np.arange(rows.size) - sn[k, 2]
        mine = owner[rows] == sowner[k]
        sn[:, 5] = np.bincount(k[mine], minlength=sn.shape[0])
        to_top = owner[rows] < 0
        order = np.lexsort((k[to_top], rows[to_top]))
        contrib = np.column_stack([k[to_top][order], place[to_top][order]]).astype(np.int64)
        cptr = np.concatenate([[0], np.cumsum(np.bincount(rows[to_top], minlength=owner.size))])
        return cptr.astype(np.int64), contrib.reshape(-1, 2)


def bins_for(threads: int | None) -> int:
    """Return how many parts the tree is dealt into, at most the threads numba has.

    ``threads``; None: ``$MSLAB_THREADS``, else numba's thread count. More parts than threads
    would only grow the serial top.
    """
    from mslab.jit import numba

    wanted = thread_count(threads) or numba().get_num_threads()
    return max(1, min(int(wanted), numba().config.NUMBA_NUM_THREADS))


def tree_factor(A: sp.spmatrix, counters: Counters, threads: int | None = None) -> TreeSolve | None:
    """Factor the symmetric positive definite ``A`` for :class:`TreeSolve` (counted in ``n_factor``).

    ``threads``: the threads the solves are split for (None: ``$MSLAB_THREADS``, else every
    thread numba has; at most as many as numba has). None when cvxopt is missing, or ``A`` is
    empty, not symmetric or not positive definite.
    """
    from mslab.integrators.newton.newton_matrix import is_symmetric

    start = time.perf_counter()
    if A.shape[0] == 0 or not is_symmetric(A):  # (L D L^T reads one triangle: a symmetric A only)
        return None
    factored = cholmod_ldlt(A)
    if factored is None:
        return None
    counters.n_factor += 1
    tree = TreeSolve(A, *factored, bins=bins_for(threads))
    tree.seconds = time.perf_counter() - start
    return tree
