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


def spring_kernel(x: np.ndarray, v: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray,
                  stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray,
                  damped: int) -> float:
    """Add the spring forces to ``f`` (n_particles, dim) in place; return the dissipated power.

    A loop over springs: the pair force ``f_q`` goes to ``+f[i]`` and ``-f[j]``;
    ``damped`` (0 or 1) skips the velocity terms when no spring is damped. A spring of
    zero length has ``u = 0`` and exerts ``-k d = 0`` (never NaN).

    For dim = 3, the common case, the loop is written out with scalars so the compiler
    keeps them in registers, in the scale form ``f_q = s d`` with
    ``s = k (L / l - 1) - c (u . Δv) / l`` (the class's formula, ``u = d / l``): fewer
    operations on the path from the loads of ``x`` to the stores into ``f`` than
    ``-k (d - L u)``, which bounds the loop (measured, ``benchmarks/spring_variants.py``).
    """
    dim = x.shape[1]
    power = 0.0
    if dim == 3 and not damped:
        for q in range(i.shape[0]):
            a = i[q]
            b = j[q]
            dx = x[a, 0] - x[b, 0]
            dy = x[a, 1] - x[b, 1]
            dz = x[a, 2] - x[b, 2]
            length = np.sqrt(dx * dx + dy * dy + dz * dz)
            s = stiffness[q] * (rest_length[q] / length - 1.0) if length > 0.0 else -stiffness[q]
            fx = s * dx
            fy = s * dy
            fz = s * dz
            f[a, 0] += fx
            f[a, 1] += fy
            f[a, 2] += fz
            f[b, 0] -= fx
            f[b, 1] -= fy
            f[b, 2] -= fz
        return power
    if dim == 3:
        for q in range(i.shape[0]):
            a = i[q]
            b = j[q]
            dx = x[a, 0] - x[b, 0]
            dy = x[a, 1] - x[b, 1]
            dz = x[a, 2] - x[b, 2]
            length = np.sqrt(dx * dx + dy * dy + dz * dz)
            inv_l = 1.0 / length if length > 0.0 else 0.0
            rate = inv_l * (dx * (v[a, 0] - v[b, 0]) + dy * (v[a, 1] - v[b, 1]) + dz * (v[a, 2] - v[b, 2]))
            cr = damping[q] * rate
            power += cr * rate
            s = stiffness[q] * (rest_length[q] * inv_l - 1.0) - cr * inv_l
            fx = s * dx
            fy = s * dy
            fz = s * dz
            f[a, 0] += fx
            f[a, 1] += fy
            f[a, 2] += fz
            f[b, 0] -= fx
            f[b, 1] -= fy
            f[b, 2] -= fz
        return power
    d = np.empty(dim)
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        length2 = 0.0
        for c in range(dim):
            d[c] = x[a, c] - x[b, c]
            length2 += d[c] * d[c]
        length = np.sqrt(length2)
        inv_l = 1.0 / length if length > 0.0 else 0.0
        k = stiffness[q]
        lu = rest_length[q] * inv_l  # L u = (L / l) d
        cr = 0.0
        if damped:
            rate = 0.0  # u . (v_i - v_j), the stretch rate
            for c in range(dim):
                rate += d[c] * inv_l * (v[a, c] - v[b, c])
            cr = damping[q] * rate
            power += cr * rate
        for c in range(dim):
            fc = -k * (d[c] - lu * d[c]) - cr * (d[c] * inv_l)
            f[a, c] += fc
            f[b, c] -= fc
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
