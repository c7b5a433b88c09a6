"""The compiled loops of the springs effect (:mod:`mslab.effects.springs`), in numba-compatible style.

The numpy methods of :class:`mslab.effects.springs.Springs` are the reference; the
functions here are the same equations as plain loops: :func:`spring_kernel` (forces and
dissipated power, composed into the stepping loops by :mod:`mslab.fast`) and
:func:`spring_jacobian_kernel` with :func:`scatter_pair_blocks` (the Jacobians of the
compiled Newton path, :mod:`mslab.fast.newton`). ``tests/test_fast.py`` and
``tests/test_newton_matrix.py`` hold them equal to the numpy code.
"""

from __future__ import annotations

import numpy as np

from mslab.jit import prange


def spring_kernel(x: np.ndarray, v: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray,
                  stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray,
                  damped: int, ranges: np.ndarray, phases: np.ndarray) -> float:
    """Add the spring forces to ``f`` (n_particles, dim) in place; return the dissipated power.

    The springs come in conflict-free batches (:mod:`mslab.effects.spring_batches`): batch
    ``r`` is springs ``ranges[r]:ranges[r+1]``, phase ``p`` is batches
    ``phases[p]:phases[p+1]``, and no two batches of one phase touch the same particle. The
    batches of a phase run on all threads (numba's ``prange``); each is summed by
    :func:`spring_range` in its own order, and the powers of the batches are added in
    batch order, so the result is bitwise the same for any number of threads. A phase of one
    batch runs on the calling thread (no parallel launch: small scenes pay nothing).

    Cost: one square root and one division per spring; work ``O(n_springs)``, span
    ``O(n_springs / n_threads)`` plus the springs of the serial phases.
    """
    n_batches = ranges.shape[0] - 1
    powers = np.empty(n_batches)  # (np.zeros would be a parallel loop of its own: a launch per call)
    for p in range(phases.shape[0] - 1):
        first = phases[p]
        last = phases[p + 1]
        if last - first > 1:
            for r in prange(first, last):
                powers[r] = spring_range(x, v, f, i, j, stiffness, rest_length, damping, damped,
                                         ranges[r], ranges[r + 1])
        else:
            for r in range(first, last):
                powers[r] = spring_range(x, v, f, i, j, stiffness, rest_length, damping, damped,
                                         ranges[r], ranges[r + 1])
    power = 0.0
    for r in range(n_batches):
        power += powers[r]
    return power


def spring_range(x: np.ndarray, v: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray,
                 stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray, damped: int,
                 start: int, stop: int) -> float:
    """Add the forces of springs ``start:stop`` to ``f``; return their dissipated power.

    The one compiled statement of a spring's force (the class's formula, ``u = d / l``)::

        f_i = s d,   s = k (L / l - 1) - c (u . Δv) / l,   f_j = -f_i

    in this scale form (fewer operations between the loads of ``x`` and the stores into
    ``f`` than ``-k (d - L u)``, which bounds the loop: measured variant by variant,
    ``benchmarks/RESULTS.md``).
    The coordinates are scalars for 1, 2 or 3 dimensions (kept in registers; the tests of
    ``dim`` and ``damped`` are the same for every spring and cost nothing measurable). A
    spring of zero length has ``1/l`` taken as 0 and exerts ``-k d = 0`` (never NaN).
    """
    dim = x.shape[1]
    power = 0.0
    for q in range(start, stop):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1] if dim > 1 else 0.0
        dz = x[a, 2] - x[b, 2] if dim > 2 else 0.0
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        inv_l = 1.0 / length if length > 0.0 else 0.0
        s = stiffness[q] * (rest_length[q] * inv_l - 1.0)
        if damped:
            rate = dx * (v[a, 0] - v[b, 0])
            if dim > 1:
                rate += dy * (v[a, 1] - v[b, 1])
            if dim > 2:
                rate += dz * (v[a, 2] - v[b, 2])
            rate *= inv_l  # u . (v_i - v_j), the stretch rate
            cr = damping[q] * rate
            power += cr * rate
            s -= cr * inv_l
        f[a, 0] += s * dx
        f[b, 0] -= s * dx
        if dim > 1:
            f[a, 1] += s * dy
            f[b, 1] -= s * dy
        if dim > 2:
            f[a, 2] += s * dz
            f[b, 2] -= s * dz
    return power


def spring_jacobian_kernel(x: np.ndarray, v: np.ndarray, i: np.ndarray, j: np.ndarray,
                           stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray,
                           damped: int, bx: np.ndarray, bv: np.ndarray) -> None:
    """Fill the blocks ``bx[q] = df_i/dx_i`` and (``damped``) ``bv[q] = df_i/dv_i`` of every spring.

    The equations of :meth:`Springs.jacobians` (class docstring) as a loop, for the
    compiled Newton path (:mod:`mslab.fast.newton`); ``bx``, ``bv`` have shape (m, dim, dim).
    """
    dim = x.shape[1]
    u = np.empty(dim)
    dv = np.empty(dim)
    pdv = np.empty(dim)
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        length2 = 0.0
        for c in range(dim):
            u[c] = x[a, c] - x[b, c]
            length2 += u[c] * u[c]
        length = np.sqrt(length2)
        inv_l = 1.0 / length if length > 0.0 else 0.0
        for c in range(dim):
            u[c] *= inv_l
        ratio = rest_length[q] * inv_l
        k = stiffness[q]
        rate = 0.0
        if damped:
            for c in range(dim):
                dv[c] = v[a, c] - v[b, c]
                rate += u[c] * dv[c]
            for c in range(dim):  # P_u dv = dv - u (u . dv)
                pdv[c] = dv[c] - u[c] * rate
        cl = damping[q] * inv_l
        for r in range(dim):
            for c in range(dim):
                uu = u[r] * u[c]
                proj = (1.0 if r == c else 0.0) - uu
                val = -k * (uu + (1.0 - ratio) * proj)
                if damped:
                    val -= cl * (u[r] * pdv[c] + rate * proj)
                    bv[q, r, c] = -damping[q] * uu
                bx[q, r, c] = val


def scatter_pair_blocks(blocks: np.ndarray, slot: np.ndarray, out: np.ndarray) -> None:
    """Add ``+B`` at (i, i), (j, j) and ``-B`` at (i, j), (j, i) into ``out`` (CSR data) at ``slot``.

    The order of :meth:`Springs._assemble`'s ``np.bincount`` (same sums, same order).
    """
    flat = blocks.ravel()
    m = flat.shape[0]
    for part in range(4):
        sign = 1.0 if part < 2 else -1.0
        base = part * m
        for e in range(m):
            out[slot[base + e]] += sign * flat[e]
