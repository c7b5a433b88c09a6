"""The local step of the fast mass-spring method, compiled on first use (:func:`mslab.jit.compiled`).

Each spring ``q = (i, j)`` with stiffness ``k`` and rest length ``L`` is projected onto its
rest length: ``d_q = L (x_i - x_j) / |x_i - x_j|`` (the closest vector of length ``L`` to
the current one; ``d_q = 0`` for a spring of zero length, whose force is zero too). The
projections are scattered as ``J d = sum_q k_q d_q (e_i - e_j)``, the right-hand side term
of the global step (Liu et al. 2013, eq. 12). Since ``J d = f_spring(x) + L x`` with ``L``
the stiffness-weighted graph Laplacian, the local step is the spring force in disguise.
"""

from __future__ import annotations

import numpy as np


def projections_py(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                   rest_length: np.ndarray, out: np.ndarray) -> None:
    """Add ``sum_q k_q d_q (e_i - e_j)`` to ``out`` (n_particles, dim) in place (plain loop)."""
    dim = x.shape[1]
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        length2 = 0.0
        for c in range(dim):
            diff = x[a, c] - x[b, c]
            length2 += diff * diff
        length = np.sqrt(length2)
        if length > 0.0:
            scale = stiffness[q] * rest_length[q] / length
            for c in range(dim):
                p = scale * (x[a, c] - x[b, c])
                out[a, c] += p
                out[b, c] -= p


def projections(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                rest_length: np.ndarray, out: np.ndarray) -> None:
    """Run the local step, compiled (:func:`mslab.jit.compiled`) on the first call.

    Parameters
    ----------
    x : ndarray, shape (n_particles, dim)
    i, j : ndarray of int64, shape (n_springs,)
    stiffness, rest_length : ndarray, shape (n_springs,)
    out : ndarray, shape (n_particles, dim)
        ``J d`` is added to it.
    """
    from mslab.jit import compiled

    local_step = compiled(projections_py, "the local step of fast_mass_spring", fastmath=False)
    local_step(x, i, j, stiffness, rest_length, out)
