"""Symbolic analysis of the float32 supernodal Cholesky (:mod:`~mslab.integrators.newton.mixed`), per pattern.

A Newton matrix of a ``d``-dimensional scene is made of dense ``d x d`` blocks, one per pair
of particles a force couples; its free dofs come in whole particles. The analysis works on
the *particle graph* (``d^2`` times smaller) and expands every particle to ``d`` columns:

1. a fill-reducing order of the particle graph (approximate minimum degree, CHOLMOD's AMD
   through cvxopt), then a postorder of its elimination tree (same fill; subtrees become
   contiguous ranges) — :func:`order_particles`;
2. the elimination tree ``parent(j)`` = the first row below the diagonal in column ``j`` of
   ``L`` (Liu's algorithm with path compression) and every column's structure,
   ``struct(j) = {i > j : A_ij != 0} + union over children c of struct(c) - {j}``
   (:func:`structure_kernel`, ``O(nnz(L))``);
3. supernodes: runs of columns with nested structures, merged with their parent supernode
   while few zeros are added (CHOLMOD's relaxed amalgamation thresholds, :data:`RELAX`): wider
   dense blocks for BLAS at the price of a few stored zeros — :func:`supernodes`.
"""

from __future__ import annotations

import numpy as np

#: relaxed amalgamation (CHOLMOD's defaults): merge a child supernode into its parent when the
#: merged one has at most ``n`` columns and a fraction of stored zeros below ``z``
RELAX = ((4, 1.0), (16, 0.8), (48, 0.1), (np.inf, 0.05))


def etree_kernel(indptr: np.ndarray, indices: np.ndarray, parent: np.ndarray, ancestor: np.ndarray) -> None:
    """Fill ``parent`` with the elimination tree of the symmetric pattern (CSR, both triangles)."""
    n = parent.size
    for j in range(n):
        parent[j] = -1
        ancestor[j] = -1
        for t in range(indptr[j], indptr[j + 1]):
            r = indices[t]
            while r != -1 and r < j:
                nxt = ancestor[r]
                ancestor[r] = j
                if nxt == -1:
                    parent[r] = j
                r = nxt


def structure_kernel(indptr: np.ndarray, indices: np.ndarray, parent: np.ndarray, child_ptr: np.ndarray,
                     children: np.ndarray, sptr: np.ndarray, sidx: np.ndarray, mark: np.ndarray) -> None:
    """Fill every column's strict lower structure of ``L`` (``sidx[sptr[j]:sptr[j + 1]]``, increasing).

    ``sptr`` must be the prefix sums of the column counts (:func:`count_kernel`); ``mark`` work (n,).
    """
    n = parent.size
    for j in range(n):
        mark[j] = -1
    for j in range(n):
        mark[j] = j
        at = sptr[j]
        for t in range(indptr[j], indptr[j + 1]):
            r = indices[t]
            if r > j and mark[r] != j:
                mark[r] = j
                sidx[at] = r
                at += 1
        for q in range(child_ptr[j], child_ptr[j + 1]):
            c = children[q]
            for t in range(sptr[c], sptr[c + 1]):
                r = sidx[t]
                if mark[r] != j:
                    mark[r] = j
                    sidx[at] = r
                    at += 1
        sidx[sptr[j]:at].sort()


def count_kernel(indptr: np.ndarray, indices: np.ndarray, parent: np.ndarray, mark: np.ndarray,
                 count: np.ndarray) -> None:
    """Return the strict column counts of ``L`` (the same sweep as :func:`structure_kernel`).

    Counts by row subtrees: row ``r`` of ``L`` holds column ``j`` iff ``j`` lies on the path from a
    ``c < r`` with ``A_rc != 0`` up to ``r`` in the tree (``O(nnz(L))``, no structure stored).
    """
    n = parent.size
    for j in range(n):
        mark[j] = -1
        count[j] = 0
    for r in range(n):
        mark[r] = r
        for t in range(indptr[r], indptr[r + 1]):
            c = indices[t]
            while c < r and c != -1 and mark[c] != r:
                mark[c] = r
                count[c] += 1
                c = parent[c]


def children_of(parent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(child_ptr, children)``: each node's children, increasing (CSR)."""
    n = parent.size
    has = parent >= 0
    kids = np.flatnonzero(has)
    order = np.argsort(parent[kids], kind="stable")
    child_ptr = np.concatenate([[0], np.cumsum(np.bincount(parent[has], minlength=n))]).astype(np.int64)
    return child_ptr, kids[order].astype(np.int64)


def postorder(parent: np.ndarray) -> np.ndarray:
    """Return a postorder of the forest ``parent`` (children before parents, subtrees contiguous)."""
    child_ptr, children = children_of(parent)
    order = []
    for root in np.flatnonzero(parent < 0):
        stack = [(int(root), False)]
        while stack:
            node, done = stack.pop()
            if done:
                order.append(node)
                continue
            stack.append((node, True))
            kids = children[child_ptr[node]:child_ptr[node + 1]]
            stack.extend((int(c), False) for c in kids[::-1])  # the smallest child first
    return np.asarray(order, dtype=np.int64)


def supernodes(parent: np.ndarray, count: np.ndarray, d: int) -> np.ndarray:
    """Return each supernode's first column (particle level, increasing; the columns postordered).

    Fundamental supernodes (``parent(j) = j + 1``, ``j`` its only child, ``count(j) = count(j+1) + 1``)
    merged bottom-up with their parent supernode when it starts right after them and the
    merged block stays within :data:`RELAX` (widths and zeros counted in dofs, ``d`` per particle).
    """
    n = parent.size
    nkids = np.bincount(parent[parent >= 0], minlength=n)
    joins = np.zeros(n, dtype=bool)
    joins[1:] = (parent[:-1] == np.arange(1, n)) & (nkids[1:] == 1) & (count[:-1] == count[1:] + 1)
    first = list(np.flatnonzero(~joins))
    last = [f - 1 for f in first[1:]] + [n - 1]
    of = np.repeat(np.arange(len(first)), np.diff(first + [n]))
    width = [lst - f + 1 for f, lst in zip(first, last, strict=True)]
    true = [float(np.sum(count[f:lst + 1] + 1)) for f, lst in zip(first, last, strict=True)]
    alive = [True] * len(first)
    for s in range(len(first)):
        up = parent[last[s]]
        if up < 0:
            continue
        p = of[up]
        if last[s] + 1 != first[p]:
            continue
        w = (width[s] + width[p]) * d
        stored = w * (w + 1) / 2 + w * count[last[p]] * d
        zeros = 1.0 - (true[s] + true[p]) * d * d / stored
        if any(w <= limit and zeros < z for limit, z in RELAX):
            first[p], width[p], true[p], alive[s] = first[s], width[s] + width[p], true[s] + true[p], False
    return np.asarray([f for f, a in zip(first, alive, strict=True) if a], dtype=np.int64)
