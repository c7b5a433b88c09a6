"""Compiled loops of Newton's matrix: Hooke springs straight into the kept pattern of ``A``.

Numba-compatible plain loops, compiled through :func:`mslab.jit.compiled` by
:mod:`mslab.fast.newton_assembly`. The equations are those of
:meth:`mslab.effects.springs.Springs.jacobians` (the numpy reference; ``tests/test_newton_matrix.py``
holds the two equal to round-off): for a spring with ``u = d / l``, ``P = I - u u^T`` and
``r = L / l``::

    df_i/dx_i = -k (u u^T + (1 - r) P)

entering ``A = M - c^2 K - c D`` with ``-`` at the blocks ``(i, i)``, ``(j, j)`` and ``+`` at
``(i, j)``, ``(j, i)``. ``clamp`` drops the term ``(1 - r) P`` of a compressed spring
(``r > 1``, where it is negative): every spring's block is then negative semidefinite and
``A`` positive definite (Choi & Ko 2002).
"""

from __future__ import annotations

import numpy as np

from mslab.effects.spring_kernels import unit_vector


def spring_newton_kernel(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                         rest_length: np.ndarray, c2: float, clamp: int, slot: np.ndarray,
                         data: np.ndarray) -> None:
    """Subtract ``c2 K`` of the springs from ``A`` (CSR values ``data``) at ``slot``.

    ``slot`` has shape (n_springs, 4, dim, dim): the position in ``data`` of entry ``(r, c)``
    of the blocks ``(i, i)``, ``(j, j)``, ``(i, j)``, ``(j, i)``; -1 where a pinned dof drops it.
    """
    dim = x.shape[1]
    u = np.empty(dim)
    for q in range(i.shape[0]):
        inv_l = unit_vector(x, i[q], j[q], u)
        t = 1.0 - rest_length[q] * inv_l
        if clamp and t < 0.0:
            t = 0.0
        k = c2 * stiffness[q]
        for r in range(dim):
            for c in range(dim):
                uu = u[r] * u[c]
                proj = (1.0 if r == c else 0.0) - uu
                lin = -k * (uu + t * proj)  # c^2 df_i/dx_i
                for part in range(4):
                    s = slot[q, part, r, c]
                    if s >= 0:
                        if part < 2:
                            data[s] -= lin
                        else:
                            data[s] += lin


def off_mass_row_sums(indptr: np.ndarray, data: np.ndarray, diagonal: np.ndarray, mass: np.ndarray,
                      inv_mass: np.ndarray, out: np.ndarray) -> float:
    """Return ``max_i inv_mass_i sum_j |A_ij - M_ij|`` (``out``: the row sums before the scaling)."""
    n = indptr.shape[0] - 1
    for r in range(n):
        s = 0.0
        for e in range(indptr[r], indptr[r + 1]):
            s += abs(data[e])
        d = data[diagonal[r]]
        s += abs(d - mass[r]) - abs(d)
        out[r] = s
    worst = 0.0
    for r in range(n):
        w = out[r] * inv_mass[r]
        if w > worst:
            worst = w
    return worst


def relative_change(data: np.ndarray, old: np.ndarray) -> float:
    """Return ``|A - A_old|_F / |A_old|_F`` for two matrices' values on one pattern."""
    diff = 0.0
    size = 0.0
    for e in range(data.shape[0]):
        d = data[e] - old[e]
        diff += d * d
        size += old[e] * old[e]
    return np.sqrt(diff / size) if size > 0.0 else np.inf


def hooke_energy_kernel(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                        rest_length: np.ndarray) -> float:
    """Return ``sum_q k (l - L)^2 / 2`` (:meth:`Springs.energy` as a loop)."""
    dim = x.shape[1]
    energy = 0.0
    for q in range(i.shape[0]):
        length2 = 0.0
        for c in range(dim):
            d = x[i[q], c] - x[j[q], c]
            length2 += d * d
        stretch = np.sqrt(length2) - rest_length[q]
        energy += 0.5 * stiffness[q] * stretch * stretch
    return energy
