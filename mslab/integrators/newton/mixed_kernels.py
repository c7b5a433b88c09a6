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

The solves (:func:`mixed_solve_kernel`) are blocked by supernode: per supernode one ``strsv``
on its diagonal block and one ``sgemv`` on the rows below it, in float32 (scipy's BLAS, again
by function pointer), the permutation, gathers and scatters in compiled loops. Float32
arithmetic adds a backward error of the order of the factor's own rounding (``|dL| <= gamma_k
|L|`` per triangular solve, ``k`` the terms of a row: ``tests/test_mixed_factor.py`` checks the
bound) and costs half the time of the float64 loops it replaced (measured in
``benchmarks/RESULTS.md``). BLAS runs on one thread (the caller limits it): the same bits on
every run and thread count on one machine (as BLAS's, they may differ between processors of
other SIMD widths).
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


def mixed_solve_kernel(b: np.ndarray, shift: float, perm: np.ndarray, sn: np.ndarray, rows: np.ndarray,
                       L: np.ndarray, y: np.ndarray, out: np.ndarray, trsv: Any, gemv: Any, ints: np.ndarray,
                       reals: np.ndarray, chars: np.ndarray) -> None:
    """``out = shift * P^T L^-T L^-1 P (b / shift)`` in float32 BLAS calls per supernode (float64 ``out``).

    ``shift``: a power of two near ``max |b|`` (the float32 work then neither overflows nor
    underflows; scaling by it is exact). ``y`` (float32, 2n): the permuted right-hand side and
    the rows gathered below a supernode (``y[n:]``). Per supernode ``s`` (columns ``f..f+k``,
    ``L11`` its ``k x k`` block, ``L21`` the ``m - k`` rows below, column-major with ``lda = m``):

    * forward: ``y_s = L11^-1 y_s`` (``strsv``), ``t = L21 y_s`` (``sgemv``), ``y[rows] -= t``;
    * backward (supernodes in reverse): ``y_s -= L21^T y[rows]`` (``sgemv``),
      ``y_s = L11^-T y_s`` (``strsv``).

    ``ints`` (int32, 4), ``reals`` (float32, 3), ``chars`` (uint8, 3): the arguments BLAS takes
    by address.
    """
    chars[0] = 76  # "L"
    chars[1] = 78  # "N"
    chars[2] = 84  # "T"
    reals[0] = 1.0
    reals[1] = 0.0
    reals[2] = -1.0
    ints[2] = 1
    n = perm.size
    inv = 1.0 / shift
    for i in range(n):
        y[i] = b[perm[i]] * inv
    gathered = y[n:]
    for s in range(sn.shape[0]):  # forward: L z = P b
        f, k, m, start, r0 = sn[s, 0], sn[s, 1], sn[s, 2], sn[s, 3], sn[s, 4]
        ints[0], ints[1], ints[3] = k, m, m - k
        ys, block, below = y[f:], L[start:], L[start + k:]
        trsv(chars[0:].ctypes, chars[1:].ctypes, chars[1:].ctypes, ints[0:].ctypes, block.ctypes,
             ints[1:].ctypes, ys.ctypes, ints[2:].ctypes)
        if m > k:
            gemv(chars[1:].ctypes, ints[3:].ctypes, ints[0:].ctypes, reals[0:].ctypes, below.ctypes,
                 ints[1:].ctypes, ys.ctypes, ints[2:].ctypes, reals[1:].ctypes, gathered.ctypes,
                 ints[2:].ctypes)
            for i in range(m - k):
                y[rows[r0 + i]] -= gathered[i]
    for s in range(sn.shape[0] - 1, -1, -1):  # backward: L^T x = z
        f, k, m, start, r0 = sn[s, 0], sn[s, 1], sn[s, 2], sn[s, 3], sn[s, 4]
        ints[0], ints[1], ints[3] = k, m, m - k
        ys, block, below = y[f:], L[start:], L[start + k:]
        if m > k:
            for i in range(m - k):
                gathered[i] = y[rows[r0 + i]]
            gemv(chars[2:].ctypes, ints[3:].ctypes, ints[0:].ctypes, reals[2:].ctypes, below.ctypes,
                 ints[1:].ctypes, gathered.ctypes, ints[2:].ctypes, reals[0:].ctypes, ys.ctypes,
                 ints[2:].ctypes)
        trsv(chars[0:].ctypes, chars[2:].ctypes, chars[1:].ctypes, ints[0:].ctypes, block.ctypes,
             ints[1:].ctypes, ys.ctypes, ints[2:].ctypes)
    for i in range(n):
        out[perm[i]] = y[i] * shift
