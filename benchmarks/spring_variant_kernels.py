"""The spring-kernel variants timed by ``benchmarks/spring_variants.py`` (issue 14).

Plain functions in numba style, compiled there. ``before`` is mslab's spring kernel as it
was before issue 14's last change (``f_q = -k (d - L u)``); the library's kernel is now the
scale form ``f_q = k (L / l - 1) d`` (``mslab.effects.spring_kernels.spring_kernel``). The others
take the undamped cloth's arguments ``(x, f, i, j, stiffness, rest_length)`` and compute the
same forces, except the ``probe_*`` functions (parts of the arithmetic left out, to see what
it costs) and ``memory_only`` (the kernel's memory accesses without its arithmetic).
"""

from __future__ import annotations

import numpy as np
from numba import njit


def before(x, v, f, i, j, stiffness, rest_length, damping, damped):
    """mslab's spring kernel before the scale form (its dim-3 branch)."""
    power = 0.0
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        inv_l = 1.0 / length if length > 0.0 else 0.0
        k = stiffness[q]
        lu = rest_length[q] * inv_l
        fx = -k * (dx - lu * dx)
        fy = -k * (dy - lu * dy)
        fz = -k * (dz - lu * dz)
        if damped:
            rate = (dx * inv_l * (v[a, 0] - v[b, 0]) + dy * inv_l * (v[a, 1] - v[b, 1])
                    + dz * inv_l * (v[a, 2] - v[b, 2]))
            cr = damping[q] * rate
            power += cr * rate
            fx -= cr * (dx * inv_l)
            fy -= cr * (dy * inv_l)
            fz -= cr * (dz * inv_l)
        f[a, 0] += fx
        f[a, 1] += fy
        f[a, 2] += fz
        f[b, 0] -= fx
        f[b, 1] -= fy
        f[b, 2] -= fz
    return power


def packed(x, f, ij, kr):
    """Indices as one (m, 2) array, stiffness and rest length as one (m, 2) array."""
    for q in range(ij.shape[0]):
        a = ij[q, 0]
        b = ij[q, 1]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        inv_l = 1.0 / length if length > 0.0 else 0.0
        k = kr[q, 0]
        lu = kr[q, 1] * inv_l
        fx = -k * (dx - lu * dx)
        fy = -k * (dy - lu * dy)
        fz = -k * (dz - lu * dz)
        f[a, 0] += fx
        f[a, 1] += fy
        f[a, 2] += fz
        f[b, 0] -= fx
        f[b, 1] -= fy
        f[b, 2] -= fz
    return 0.0


def blocked(x, f, i, j, stiffness, rest_length, width):
    """Blocks of ``width`` springs: gather the differences, then the square roots and divisions
    of the block in one loop (vectorisable: SIMD lanes), then scatter; same operations and
    rounding as the plain loop, buffers small enough for the L1 cache."""
    m = i.shape[0]
    bx = np.empty(width)
    by = np.empty(width)
    bz = np.empty(width)
    bl = np.empty(width)
    for q0 in range(0, m, width):
        nb = min(width, m - q0)
        for t in range(nb):
            a = i[q0 + t]
            b = j[q0 + t]
            dx = x[a, 0] - x[b, 0]
            dy = x[a, 1] - x[b, 1]
            dz = x[a, 2] - x[b, 2]
            bx[t] = dx
            by[t] = dy
            bz[t] = dz
            bl[t] = dx * dx + dy * dy + dz * dz
        for t in range(nb):
            length = np.sqrt(bl[t])
            inv_l = 1.0 / length  # unconditional (inf at 0, replaced): the loop vectorises
            inv_l = inv_l if length > 0.0 else 0.0
            bl[t] = rest_length[q0 + t] * inv_l
        for t in range(nb):
            a = i[q0 + t]
            b = j[q0 + t]
            k = stiffness[q0 + t]
            lu = bl[t]
            dx = bx[t]
            dy = by[t]
            dz = bz[t]
            fx = -k * (dx - lu * dx)
            fy = -k * (dy - lu * dy)
            fz = -k * (dz - lu * dz)
            f[a, 0] += fx
            f[a, 1] += fy
            f[a, 2] += fz
            f[b, 0] -= fx
            f[b, 1] -= fy
            f[b, 2] -= fz
    return 0.0


def scale_parallel(x, f, i, j, stiffness, rest_length):
    """Scale form with the square root and the division side by side: ``L / l = L sqrt(l2) / l2``."""
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        l2 = dx * dx + dy * dy + dz * dz
        k = stiffness[q]
        s = k * ((rest_length[q] * np.sqrt(l2)) * (1.0 / l2) - 1.0) if l2 > 0.0 else -k
        f[a, 0] += s * dx
        f[a, 1] += s * dy
        f[a, 2] += s * dz
        f[b, 0] -= s * dx
        f[b, 1] -= s * dy
        f[b, 2] -= s * dz
    return 0.0


def scale_parallel_guarded(x, f, i, j, stiffness, rest_length):
    """As :func:`scale_parallel`, safe for the tiniest lengths (``1 / l2`` would overflow)."""
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        l2 = dx * dx + dy * dy + dz * dz
        k = stiffness[q]
        if l2 > 1e-300:
            s = k * ((rest_length[q] * np.sqrt(l2)) * (1.0 / l2) - 1.0)
        elif l2 > 0.0:  # 1 / l2 would overflow
            s = k * (rest_length[q] / np.sqrt(l2) - 1.0)
        else:
            s = -k
        f[a, 0] += s * dx
        f[a, 1] += s * dy
        f[a, 2] += s * dz
        f[b, 0] -= s * dx
        f[b, 1] -= s * dy
        f[b, 2] -= s * dz
    return 0.0


def scale_pair(x, f, i, j, stiffness, rest_length):
    """Scale form, two springs per iteration (their arithmetic interleaved; stores in table order)."""
    m = i.shape[0]
    for q in range(0, m, 2):
        r = min(q + 1, m - 1)  # an odd count: the last spring twice, its second force zeroed
        a = i[q]
        b = j[q]
        c = i[r]
        e = j[r]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        ex = x[c, 0] - x[e, 0]
        ey = x[c, 1] - x[e, 1]
        ez = x[c, 2] - x[e, 2]
        l1 = np.sqrt(dx * dx + dy * dy + dz * dz)
        l2 = np.sqrt(ex * ex + ey * ey + ez * ez)
        i1 = 1.0 / l1 if l1 > 0.0 else 0.0
        i2 = 1.0 / l2 if l2 > 0.0 else 0.0
        s1 = stiffness[q] * (rest_length[q] * i1 - 1.0)
        s2 = stiffness[r] * (rest_length[r] * i2 - 1.0) if r > q else 0.0
        f[a, 0] += s1 * dx
        f[a, 1] += s1 * dy
        f[a, 2] += s1 * dz
        f[b, 0] -= s1 * dx
        f[b, 1] -= s1 * dy
        f[b, 2] -= s1 * dz
        f[c, 0] += s2 * ex
        f[c, 1] += s2 * ey
        f[c, 2] += s2 * ez
        f[e, 0] -= s2 * ex
        f[e, 1] -= s2 * ey
        f[e, 2] -= s2 * ez
    return 0.0


def scale_pipelined(x, f, i, j, stiffness, rest_length):
    """Scale form, software-pipelined: the differences of spring q+1 are loaded before spring q is
    scattered (the loop carries them)."""
    m = i.shape[0]
    if m == 0:
        return 0.0
    a = i[0]
    b = j[0]
    dx = x[a, 0] - x[b, 0]
    dy = x[a, 1] - x[b, 1]
    dz = x[a, 2] - x[b, 2]
    for q in range(m):
        r = q + 1 if q + 1 < m else q
        c = i[r]
        e = j[r]
        ex = x[c, 0] - x[e, 0]
        ey = x[c, 1] - x[e, 1]
        ez = x[c, 2] - x[e, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        s = stiffness[q] * (rest_length[q] / length - 1.0) if length > 0.0 else -stiffness[q]
        f[a, 0] += s * dx
        f[a, 1] += s * dy
        f[a, 2] += s * dz
        f[b, 0] -= s * dx
        f[b, 1] -= s * dy
        f[b, 2] -= s * dz
        a = c
        b = e
        dx = ex
        dy = ey
        dz = ez
    return 0.0


def scale_newton(x, f, i, j, stiffness, rest_length):
    """Scale form with ``1 / l`` from a float32 seed and two Newton steps in float64 (no double
    square root or division; ~1 ulp from ``1 / sqrt(l2)``)."""
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        l2 = dx * dx + dy * dy + dz * dz
        y = np.float64(np.float32(1.0) / np.sqrt(np.float32(l2)))
        h = 0.5 * l2
        y = y * (1.5 - h * y * y)
        y = y * (1.5 - h * y * y)
        k = stiffness[q]
        s = k * (rest_length[q] * y - 1.0) if l2 > 0.0 else -k
        f[a, 0] += s * dx
        f[a, 1] += s * dy
        f[a, 2] += s * dz
        f[b, 0] -= s * dx
        f[b, 1] -= s * dy
        f[b, 2] -= s * dz
    return 0.0


def probe_no_division(x, f, i, j, stiffness, rest_length):
    """Probe (wrong forces): the scale form without its division."""
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        s = stiffness[q] * (rest_length[q] * length - 1.0) if length > 0.0 else -stiffness[q]
        f[a, 0] += s * dx
        f[a, 1] += s * dy
        f[a, 2] += s * dz
        f[b, 0] -= s * dx
        f[b, 1] -= s * dy
        f[b, 2] -= s * dz
    return 0.0


def probe_no_sqrt(x, f, i, j, stiffness, rest_length):
    """Probe (wrong forces): the scale form without its square root."""
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        length = dx * dx + dy * dy + dz * dz
        s = stiffness[q] * (rest_length[q] / length - 1.0) if length > 0.0 else -stiffness[q]
        f[a, 0] += s * dx
        f[a, 1] += s * dy
        f[a, 2] += s * dz
        f[b, 0] -= s * dx
        f[b, 1] -= s * dy
        f[b, 2] -= s * dz
    return 0.0


def memory_only(x, f, i, j, stiffness, rest_length):
    """The kernel's memory accesses without its arithmetic: a lower bound on its time."""
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        s = stiffness[q] + rest_length[q]
        f[a, 0] += s * x[b, 0]
        f[a, 1] += x[b, 1]
        f[a, 2] += x[b, 2]
        f[b, 0] -= x[a, 0]
        f[b, 1] -= x[a, 1]
        f[b, 2] -= x[a, 2]
    return 0.0


def greedy_order(i: np.ndarray, j: np.ndarray, window: int = 4, look: int = 64) -> np.ndarray:
    """A permutation of the springs in which no ``window`` consecutive springs share a particle.

    Walks the table in its order: the next spring is the first still pending (of the next
    ``look``) whose particles are not touched by the last ``window`` springs placed; when
    there is none, the first pending one. Locality stays that of the table's order.
    """
    return _greedy(np.ascontiguousarray(i, dtype=np.int64), np.ascontiguousarray(j, dtype=np.int64),
                   window, look)


@njit(cache=False)
def _greedy(i, j, window, look):
    m = i.size
    n = max(i.max(), j.max()) + 1 if m else 0
    last = np.full(n, -(10**9), dtype=np.int64)  # output slot of the last spring touching p
    done = np.zeros(m, dtype=np.bool_)
    out = np.empty(m, dtype=np.int64)
    first = 0  # first pending spring
    for slot in range(m):
        while done[first]:
            first += 1
        pick = first
        q = first
        seen = 0
        while q < m and seen < look:
            if not done[q]:
                if slot - last[i[q]] > window and slot - last[j[q]] > window:
                    pick = q
                    break
                seen += 1
            q += 1
        done[pick] = True
        out[slot] = pick
        last[i[pick]] = slot
        last[j[pick]] = slot
    return out


def shared_neighbours(i: np.ndarray, j: np.ndarray) -> int:
    """Count consecutive springs that share a particle."""
    return int(np.sum((i[1:] == i[:-1]) | (i[1:] == j[:-1]) | (j[1:] == i[:-1]) | (j[1:] == j[:-1])))
