"""Compiled loops of the float32 supernodal Cholesky factorisation (:mod:`~mslab.integrators.newton.mixed`).

Plain functions in numba's subset of Python, compiled by :func:`mslab.jit.compiled`. The
numeric factorisation is *multifrontal*: supernode ``s`` (``k`` columns, front rows ``R_s``
of which its own columns come first, ``m = |R_s|``) assembles the dense lower front

    F = A[R_s, cols(s)] + sum over its children c of U_c (scattered into R_s)

and factors its first ``k`` columns with LAPACK/BLAS in float32 (column-major, ``lda = m``)::

    F11 = L11 L11^T                (spotrf, k^3/3 flops)
    L21 = F21 L11^-T               (strsm, (m-k) k^2 flops)
    U_s = F22 - L21 L21^T          (ssyrk, (m-k)^2 k flops: most of the work)

``[L11; L21]`` is stored, ``U_s`` is pushed on a stack for the parent (supernodes come in a
postorder of their tree, so a parent's children's updates are the top of the stack). The
BLAS and LAPACK routines are scipy's (``scipy.linalg.cython_blas``/``cython_lapack``), passed
in as function pointers so that numba can cache the loop. Everything runs on one thread in a
fixed order (BLAS limited to one thread by the caller): the same bits on every run.

The solves read the float32 factor and compute in float64 (``x = P^T L^-T L^-1 P b``): the
preconditioner's only error is the factor's rounding. They are compiled with fast-math (the
backward solve's sums vectorised, products and sums fused; the loops hold no comparison a
NaN could mislead, and a NaN still reaches CG, which then stops): the order is fixed by the
compiled code, so the bits are the same on every run and thread count on one machine (as
BLAS's, they may differ between processors of other SIMD widths).
"""

from __future__ import annotations

from typing import Any

import numpy as np


def mixed_factor_kernel(data: np.ndarray, scale: float, tiny: float, a_ptr: np.ndarray, a_slot: np.ndarray,
                        a_pos: np.ndarray, sn: np.ndarray, children: np.ndarray, child_ptr: np.ndarray,
                        rel: np.ndarray, L: np.ndarray, front: np.ndarray, stack: np.ndarray, potrf: Any,
                        trsm: Any, syrk: Any, ints: np.ndarray, reals: np.ndarray, chars: np.ndarray) -> int:
    """Factor the matrix with values ``scale * data`` (``data`` float64, on the kept pattern) into ``L``.

    Entries of ``L`` and of the updates below ``tiny`` in magnitude are stored as zeros: the
    factor of a mesh's matrix decays with the distance in the mesh, and float32 numbers below
    1.2e-38 (subnormal) cost the processor a hundred cycles each (measured: the factorisation
    took 9x longer with them). With ``scale = 1 / max diag(A)`` and ``tiny = 2^-50`` they are
    far below the factor's rounding (``2^-24`` relative).

    ``sn[s]`` = (first column, k, m, start in ``L``, start in ``rel`` and ``rows``);
    ``a_ptr``/``a_slot``/``a_pos``: the entries of ``A`` in supernode ``s``'s front (slot in
    ``data``, place in the column-major front); ``children``/``child_ptr``: each supernode's
    children, increasing; ``rel``: each supernode's rows below its columns, as places in its
    parent's front. ``ints`` (int32, 8), ``reals`` (float32, 2) and ``chars`` (uint8, 8) hold the
    arguments BLAS takes by address. Returns 0, or ``s + 1`` for the first supernode whose
    diagonal block is not positive definite in float32.
    """
    chars[0] = 76  # "L"
    chars[1] = 82  # "R"
    chars[2] = 84  # "T"
    chars[3] = 78  # "N"
    reals[0] = 1.0
    reals[1] = -1.0
    top = 0
    for s in range(sn.shape[0]):
        k, m = sn[s, 1], sn[s, 2]
        for j in range(m):  # the lower triangle: nothing reads the upper one
            for i in range(j * m + j, j * m + m):
                front[i] = 0.0
        for t in range(a_ptr[s], a_ptr[s + 1]):
            front[a_pos[t]] += data[a_slot[t]] * scale
        for q in range(child_ptr[s + 1] - 1, child_ptr[s] - 1, -1):  # the last child's update is on top
            c = children[q]
            mu = sn[c, 2] - sn[c, 1]
            base = top - mu * mu
            r0 = sn[c, 4]
            for jj in range(mu):
                col = rel[r0 + jj] * m
                src = base + jj * mu
                for ii in range(jj, mu):
                    front[col + rel[r0 + ii]] += stack[src + ii]
            top = base
        ints[0] = k
        ints[1] = m
        ints[2] = m - k
        ints[3] = 0
        potrf(chars[0:].ctypes, ints[0:].ctypes, front.ctypes, ints[1:].ctypes, ints[3:].ctypes)
        if ints[3] != 0:
            return s + 1
        if m > k:
            tail = front[k:]
            trsm(chars[1:].ctypes, chars[0:].ctypes, chars[2:].ctypes, chars[3:].ctypes,
                 ints[2:].ctypes, ints[0:].ctypes, reals[0:].ctypes, front.ctypes, ints[1:].ctypes,
                 tail.ctypes, ints[1:].ctypes)
            corner = front[k + k * m:]
            syrk(chars[0:].ctypes, chars[3:].ctypes, ints[2:].ctypes, ints[0:].ctypes, reals[1:].ctypes,
                 tail.ctypes, ints[1:].ctypes, reals[0:].ctypes, corner.ctypes, ints[1:].ctypes)
        start = sn[s, 3]
        for j in range(k):
            for i in range(j, m):
                v = front[j * m + i]
                L[start + j * m + i] = v if abs(v) >= tiny else 0.0
        mu = m - k
        for jj in range(mu):
            src = k + (k + jj) * m
            dst = top + jj * mu
            for ii in range(jj, mu):
                v = front[src + ii]
                stack[dst + ii] = v if abs(v) >= tiny else 0.0
        top += mu * mu
    return 0


def mixed_solve_kernel(b: np.ndarray, scale: float, perm: np.ndarray, sn: np.ndarray, rows: np.ndarray,
                       L: np.ndarray, y: np.ndarray, out: np.ndarray) -> None:
    """``out = A^-1 b`` approximately: ``scale P^T L^-T L^-1 P b`` (``L L^T ~ scale P A P^T``), in float64.

    ``rows``: every supernode's rows below its columns (starting at ``sn[s, 4]``); ``y``: work
    (n,) and (n,) more for the gathered rows (``y[n:]``).
    """
    n = perm.size
    for i in range(n):
        y[i] = b[perm[i]]
    for s in range(sn.shape[0]):  # forward: L z = P b
        f, k, m, start, r0 = sn[s, 0], sn[s, 1], sn[s, 2], sn[s, 3], sn[s, 4]
        for j in range(k):
            col = start + j * m
            yj = y[f + j] / L[col + j]
            y[f + j] = yj
            for i in range(j + 1, k):
                y[f + i] -= L[col + i] * yj
        below = m - k
        acc = y[n:n + below]
        for i in range(below):
            acc[i] = 0.0
        j = 0
        while j < k:  # four columns at a time: one pass over acc per four columns of L
            c0 = start + j * m + k
            y0 = y[f + j]
            if j + 4 <= k:
                y1, y2, y3 = y[f + j + 1], y[f + j + 2], y[f + j + 3]
                for i in range(below):
                    acc[i] += ((L[c0 + i] * y0 + L[c0 + m + i] * y1)
                               + (L[c0 + 2 * m + i] * y2 + L[c0 + 3 * m + i] * y3))
                j += 4
            else:
                for i in range(below):
                    acc[i] += L[c0 + i] * y0
                j += 1
        for i in range(below):
            y[rows[r0 + i]] -= acc[i]
    for s in range(sn.shape[0] - 1, -1, -1):  # backward: L^T x = z
        f, k, m, start, r0 = sn[s, 0], sn[s, 1], sn[s, 2], sn[s, 3], sn[s, 4]
        below = m - k
        g = y[n:n + below]
        for i in range(below):
            g[i] = y[rows[r0 + i]]
        for j in range(k):
            c0 = start + j * m + k
            dot = 0.0
            for i in range(below):  # a sum numba vectorises (compiled with fast-math)
                dot += L[c0 + i] * g[i]
            y[f + j] -= dot
        for j in range(k - 1, -1, -1):
            col = start + j * m
            yj = y[f + j]
            for i in range(j + 1, k):
                yj -= L[col + i] * y[f + i]
            y[f + j] = yj / L[col + j]
    for i in range(n):
        out[perm[i]] = y[i] * scale
