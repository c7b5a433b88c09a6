"""The compiled loops of the kept L D L^T solves on every core (:mod:`mslab.integrators.newton.tree_solve`).

Numba's subset of Python, compiled by :func:`mslab.jit.compiled` (the plain helpers of this
module with the function that calls them). Three right-hand sides at a time (the coordinates
of a 3D scene; fewer are padded with zeros): written out as three scalars, the loops keep
them in registers and read ``L`` once for all three. Every ``y[r]`` gets its subtractions in
increasing column order however the tree is split (the module docstring of ``tree_solve``):

* :func:`tree_solve_kernel`: one solve;
* :func:`local_global_loop`: the fast mass-spring method's iterations (local step, solve,
  update) with one parallel launch per iteration
  (:mod:`mslab.integrators.families.local_global_tree`).
"""

from __future__ import annotations

import numpy as np

from mslab.jit import prange


def tree_solve_kernel(perm: np.ndarray, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                      inner_end: np.ndarray, diagonal: np.ndarray, nodes: np.ndarray, offsets: np.ndarray,
                      top: np.ndarray, top_ptr: np.ndarray, top_cols: np.ndarray, top_vals: np.ndarray,
                      b: np.ndarray, y: np.ndarray, out: np.ndarray) -> None:
    """``out = A^-1 b`` for ``b`` (n, 3): ``y = P b``, forward, ``D^-1``, backward, ``out = P^T y``.

    The threads' subtrees (``nodes[offsets[t]:offsets[t+1]]``, increasing) run in parallel,
    the top (``top``, increasing; its rows of L in ``top_ptr/top_cols/top_vals``) on the
    calling thread: after them going forward, before them going back.
    """
    n = perm.shape[0]
    for r in range(n):
        p = perm[r]
        y[r, 0] = b[p, 0]
        y[r, 1] = b[p, 1]
        y[r, 2] = b[p, 2]
    bins = offsets.shape[0] - 1
    if bins > 1:
        for t in prange(bins):
            forward_nodes(indptr, indices, data, inner_end, nodes, offsets[t], offsets[t + 1], y)
    else:
        forward_nodes(indptr, indices, data, inner_end, nodes, 0, nodes.shape[0], y)
    top_solve(indptr, indices, data, diagonal, top, top_ptr, top_cols, top_vals, y)
    if bins > 1:
        for t in prange(bins):
            backward_nodes(indptr, indices, data, diagonal, nodes, offsets[t], offsets[t + 1], y)
    else:
        backward_nodes(indptr, indices, data, diagonal, nodes, 0, nodes.shape[0], y)
    for r in range(n):
        p = perm[r]
        out[p, 0] = y[r, 0]
        out[p, 1] = y[r, 1]
        out[p, 2] = y[r, 2]


def forward_nodes(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, inner_end: np.ndarray,
                  nodes: np.ndarray, first: int, last: int, y: np.ndarray) -> None:
    """Sweep forward over ``nodes[first:last]`` (increasing): ``y[r] -= L[r, c] y[c]`` in their subtrees."""
    for s in range(first, last):
        c = nodes[s]
        y0 = y[c, 0]
        y1 = y[c, 1]
        y2 = y[c, 2]
        for q in range(indptr[c], inner_end[c]):
            r = indices[q]
            lv = data[q]
            y[r, 0] -= lv * y0
            y[r, 1] -= lv * y1
            y[r, 2] -= lv * y2


def top_solve(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, diagonal: np.ndarray,
              top: np.ndarray, top_ptr: np.ndarray, top_cols: np.ndarray, top_vals: np.ndarray,
              y: np.ndarray) -> None:
    """Solve the top of the tree after the subtrees' forward sweeps: forward rows, ``D^-1``, backward."""
    for s in range(top.shape[0]):
        r = top[s]
        a0 = y[r, 0]
        a1 = y[r, 1]
        a2 = y[r, 2]
        for q in range(top_ptr[s], top_ptr[s + 1]):
            c = top_cols[q]
            lv = top_vals[q]
            a0 -= lv * y[c, 0]
            a1 -= lv * y[c, 1]
            a2 -= lv * y[c, 2]
        y[r, 0] = a0
        y[r, 1] = a1
        y[r, 2] = a2
    for s in range(top.shape[0] - 1, -1, -1):
        backward_column(indptr, indices, data, diagonal, top[s], y)


def backward_nodes(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, diagonal: np.ndarray,
                   nodes: np.ndarray, first: int, last: int, y: np.ndarray) -> None:
    """Sweep backward over ``nodes[first:last]`` (decreasing), after the top's."""
    for s in range(last - 1, first - 1, -1):
        backward_column(indptr, indices, data, diagonal, nodes[s], y)


def backward_column(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, diagonal: np.ndarray,
                    c: int, y: np.ndarray) -> None:
    """``x[c] = y[c] / D[c] - sum_r L[r, c] x[r]`` (rows increasing), in place."""
    d = diagonal[c]
    a0 = y[c, 0] / d
    a1 = y[c, 1] / d
    a2 = y[c, 2] / d
    for q in range(indptr[c], indptr[c + 1]):
        r = indices[q]
        lv = data[q]
        a0 -= lv * y[r, 0]
        a1 -= lv * y[r, 1]
        a2 -= lv * y[r, 2]
    y[c, 0] = a0
    y[c, 1] = a1
    y[c, 2] = a2
