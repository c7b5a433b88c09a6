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


def tree_solve_kernel(perm: np.ndarray, sn: np.ndarray, rows: np.ndarray, blk: np.ndarray, tri: np.ndarray,
                      diagonal: np.ndarray, sowner: np.ndarray, sn_order: np.ndarray, sn_offsets: np.ndarray,
                      top_sn: np.ndarray, cptr: np.ndarray, contrib: np.ndarray, buffer: np.ndarray,
                      widest: int, b: np.ndarray, y: np.ndarray, out: np.ndarray) -> None:
    """``out = A^-1 b`` for ``b`` (n, 3): ``y = P b``, forward, ``D^-1``, backward, ``out = P^T y``.

    The threads' supernodes (``sn_order[sn_offsets[t]:sn_offsets[t+1]]``, increasing) run
    in parallel, the top's (``top_sn``) on the calling thread: after them going forward,
    before them going back.
    """
    n = perm.shape[0]
    for r in range(n):
        p = perm[r]
        y[r, 0] = b[p, 0]
        y[r, 1] = b[p, 1]
        y[r, 2] = b[p, 2]
    bins = sn_offsets.shape[0] - 1
    if bins > 1:
        for t in prange(bins):
            forward_supernodes(sn, rows, blk, tri, sn_order, sn_offsets[t], sn_offsets[t + 1], y, buffer)
    else:
        forward_supernodes(sn, rows, blk, tri, sn_order, 0, sn_order.shape[0], y, buffer)
    top_solve(sn, rows, blk, tri, diagonal, sowner, top_sn, cptr, contrib, buffer, widest, y)
    if bins > 1:
        for t in prange(bins):
            backward_supernodes(sn, rows, blk, tri, diagonal, sn_order, sn_offsets[t], sn_offsets[t + 1],
                                widest, y)
    else:
        backward_supernodes(sn, rows, blk, tri, diagonal, sn_order, 0, sn_order.shape[0], widest, y)
    for r in range(n):
        p = perm[r]
        out[p, 0] = y[r, 0]
        out[p, 1] = y[r, 1]
        out[p, 2] = y[r, 2]


def forward_supernodes(sn: np.ndarray, rows: np.ndarray, blk: np.ndarray, tri: np.ndarray, order: np.ndarray,
                       first: int, last: int, y: np.ndarray, buffer: np.ndarray) -> None:
    """Sweep forward over the supernodes ``order[first:last]`` (increasing) of one thread.

    Each: its triangle (``y[c+a] -= L[c+a, c+b] y[c+b]``, ``b`` increasing), then for each
    row ``r`` of ``R`` the sum ``v = sum_m L[r, c+m] y[c+m]`` (``m`` increasing), subtracted
    from ``y[r]`` for the thread's own rows and kept in ``buffer`` for the top's. Four rows
    at a time (twelve sums in registers: the additions of one row stay in order); a
    one-column supernode in one loop (the same sums: ``0 + L[r, c] y[c]``).
    """
    for s in range(first, last):
        k = order[s]
        c = sn[k, 0]
        w = sn[k, 1]
        below = sn[k, 6]
        at = sn[k, 3]
        if w == 1:  # one column: y[r] -= L[r, c] y[c]
            y0 = y[c, 0]
            y1 = y[c, 1]
            y2 = y[c, 2]
            start = sn[k, 2]
            inner = sn[k, 5]
            for i in range(inner):
                r = rows[start + i]
                lv = blk[at + i]
                y[r, 0] -= 0.0 + lv * y0
                y[r, 1] -= 0.0 + lv * y1
                y[r, 2] -= 0.0 + lv * y2
            for i in range(inner, below):
                lv = blk[at + i]
                buffer[start + i, 0] = 0.0 + lv * y0
                buffer[start + i, 1] = 0.0 + lv * y1
                buffer[start + i, 2] = 0.0 + lv * y2
            continue
        triangle_forward(tri, sn[k, 4], c, w, y)
        i = 0
        while i + 4 <= below:
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            b0 = 0.0
            b1 = 0.0
            b2 = 0.0
            c0 = 0.0
            c1 = 0.0
            c2 = 0.0
            d0 = 0.0
            d1 = 0.0
            d2 = 0.0
            ra = at + i * w
            for m in range(w):
                y0 = y[c + m, 0]
                y1 = y[c + m, 1]
                y2 = y[c + m, 2]
                la = blk[ra + m]
                lb = blk[ra + w + m]
                lc = blk[ra + 2 * w + m]
                ld = blk[ra + 3 * w + m]
                a0 += la * y0
                a1 += la * y1
                a2 += la * y2
                b0 += lb * y0
                b1 += lb * y1
                b2 += lb * y2
                c0 += lc * y0
                c1 += lc * y1
                c2 += lc * y2
                d0 += ld * y0
                d1 += ld * y1
                d2 += ld * y2
            put_row(sn, rows, k, i, a0, a1, a2, y, buffer)
            put_row(sn, rows, k, i + 1, b0, b1, b2, y, buffer)
            put_row(sn, rows, k, i + 2, c0, c1, c2, y, buffer)
            put_row(sn, rows, k, i + 3, d0, d1, d2, y, buffer)
            i += 4
        while i < below:
            v0, v1, v2 = row_sum(blk, at + i * w, c, w, y)
            put_row(sn, rows, k, i, v0, v1, v2, y, buffer)
            i += 1


def put_row(sn: np.ndarray, rows: np.ndarray, k: int, i: int, v0: float, v1: float, v2: float,
            y: np.ndarray, buffer: np.ndarray) -> None:
    """Subtract supernode ``k``'s sum for its ``i``-th row from ``y`` (its thread's row), else keep it."""
    place = sn[k, 2] + i
    if i < sn[k, 5]:
        r = rows[place]
        y[r, 0] -= v0
        y[r, 1] -= v1
        y[r, 2] -= v2
    else:
        buffer[place, 0] = v0
        buffer[place, 1] = v1
        buffer[place, 2] = v2


def row_sum(blk: np.ndarray, at: int, c: int, w: int, y: np.ndarray) -> tuple[float, float, float]:
    """Return ``sum_m blk[at + m] y[c + m]`` for the three columns (``m`` increasing)."""
    v0 = 0.0
    v1 = 0.0
    v2 = 0.0
    for m in range(w):
        lv = blk[at + m]
        v0 += lv * y[c + m, 0]
        v1 += lv * y[c + m, 1]
        v2 += lv * y[c + m, 2]
    return v0, v1, v2


def triangle_forward(tri: np.ndarray, at: int, c: int, w: int, y: np.ndarray) -> None:
    """``y[c+a] -= sum_b L[c+a, c+b] y[c+b]`` for ``b < a`` (increasing), ``a`` increasing: unit lower."""
    for a in range(1, w):
        s0 = y[c + a, 0]
        s1 = y[c + a, 1]
        s2 = y[c + a, 2]
        row = at + a * w
        for b in range(a):
            lv = tri[row + b]
            s0 -= lv * y[c + b, 0]
            s1 -= lv * y[c + b, 1]
            s2 -= lv * y[c + b, 2]
        y[c + a, 0] = s0
        y[c + a, 1] = s1
        y[c + a, 2] = s2


def top_solve(sn: np.ndarray, rows: np.ndarray, blk: np.ndarray, tri: np.ndarray, diagonal: np.ndarray,
              sowner: np.ndarray, top_sn: np.ndarray, cptr: np.ndarray, contrib: np.ndarray,
              buffer: np.ndarray, widest: int, y: np.ndarray) -> None:
    """Solve the top of the tree after the threads' forward sweeps: forward, ``D^-1``, backward.

    Forward row by row: every supernode's sum for the row (from the buffer for a thread's,
    computed here for the top's; supernodes increasing), then the row's own triangle.
    """
    for s in range(top_sn.shape[0]):
        k = top_sn[s]
        c = sn[k, 0]
        w = sn[k, 1]
        for a in range(w):
            r = c + a
            s0 = y[r, 0]
            s1 = y[r, 1]
            s2 = y[r, 2]
            for q in range(cptr[r], cptr[r + 1]):
                j = contrib[q, 0]
                i = contrib[q, 1]
                if sowner[j] >= 0:
                    v0 = buffer[sn[j, 2] + i, 0]
                    v1 = buffer[sn[j, 2] + i, 1]
                    v2 = buffer[sn[j, 2] + i, 2]
                else:
                    v0, v1, v2 = row_sum(blk, sn[j, 3] + i * sn[j, 1], sn[j, 0], sn[j, 1], y)
                s0 -= v0
                s1 -= v1
                s2 -= v2
            y[r, 0] = s0
            y[r, 1] = s1
            y[r, 2] = s2
        triangle_forward(tri, sn[k, 4], c, w, y)
    backward_supernodes(sn, rows, blk, tri, diagonal, top_sn, 0, top_sn.shape[0], widest, y)


def backward_supernodes(sn: np.ndarray, rows: np.ndarray, blk: np.ndarray, tri: np.ndarray,
                        diagonal: np.ndarray, order: np.ndarray, first: int, last: int, widest: int,
                        y: np.ndarray) -> None:
    """Sweep backward over the supernodes ``order[first:last]`` (decreasing), after their ancestors.

    Each: ``acc[m] = sum_i L[R[i], c+m] x[R[i]]`` (``i`` increasing), then from the last
    column: ``x[c+a] = y[c+a] / D - acc[a] - sum_b L[c+b, c+a] x[c+b]`` (``b`` increasing).
    """
    acc = np.empty((3, widest))
    for s in range(last - 1, first - 1, -1):
        k = order[s]
        c = sn[k, 0]
        w = sn[k, 1]
        below_sums(sn, rows, blk, k, y, acc)
        t = sn[k, 4]
        for a in range(w - 1, -1, -1):
            d = diagonal[c + a]
            s0 = y[c + a, 0] / d - acc[0, a]
            s1 = y[c + a, 1] / d - acc[1, a]
            s2 = y[c + a, 2] / d - acc[2, a]
            for bb in range(a + 1, w):
                lv = tri[t + bb * w + a]
                s0 -= lv * y[c + bb, 0]
                s1 -= lv * y[c + bb, 1]
                s2 -= lv * y[c + bb, 2]
            y[c + a, 0] = s0
            y[c + a, 1] = s1
            y[c + a, 2] = s2


def below_sums(sn: np.ndarray, rows: np.ndarray, blk: np.ndarray, k: int, y: np.ndarray,
               acc: np.ndarray) -> None:
    """``acc[:, m] = sum_i L[R[i], c+m] x[R[i]]`` for supernode ``k`` (``i`` increasing, from 0).

    Four columns at a time: twelve sums in registers, each one's additions in row order.
    """
    w = sn[k, 1]
    at = sn[k, 3]
    start = sn[k, 2]
    below = sn[k, 6]
    m = 0
    while m < w:  # four columns at a time: twelve sums in registers, rows i increasing
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        b0 = 0.0
        b1 = 0.0
        b2 = 0.0
        c0 = 0.0
        c1 = 0.0
        c2 = 0.0
        d0 = 0.0
        d1 = 0.0
        d2 = 0.0
        four = m + 4 <= w
        for i in range(below):
            r = rows[start + i]
            x0 = y[r, 0]
            x1 = y[r, 1]
            x2 = y[r, 2]
            row = at + i * w + m
            la = blk[row]
            a0 += la * x0
            a1 += la * x1
            a2 += la * x2
            if four:
                lb = blk[row + 1]
                lc = blk[row + 2]
                ld = blk[row + 3]
                b0 += lb * x0
                b1 += lb * x1
                b2 += lb * x2
                c0 += lc * x0
                c1 += lc * x1
                c2 += lc * x2
                d0 += ld * x0
                d1 += ld * x1
                d2 += ld * x2
        acc[0, m] = a0
        acc[1, m] = a1
        acc[2, m] = a2
        if four:
            acc[0, m + 1] = b0
            acc[1, m + 1] = b1
            acc[2, m + 1] = b2
            acc[0, m + 2] = c0
            acc[1, m + 2] = c1
            acc[2, m + 2] = c2
            acc[0, m + 3] = d0
            acc[1, m + 3] = d1
            acc[2, m + 3] = d2
            m += 4
        else:
            m += 1
