"""Exercise 01: Hooke spring forces and their Jacobian (lecture notes, eqs. 1-2)."""

import numpy as np


def spring_forces(x, springs, stiffness, rest_length):
    """Total spring force on every particle.

    Parameters
    ----------
    x : ndarray, shape (n_particles, dim)
        Positions.
    springs : ndarray of int, shape (n_springs, 2)
        Particle pairs ``(i, j)`` joined by a spring.
    stiffness, rest_length : ndarray, shape (n_springs,)
        Spring constants ``k`` and rest lengths ``L``.

    Returns
    -------
    f : ndarray, shape (n_particles, dim)
        ``f_i = sum over springs (i, j) of k (L - l) (x_i - x_j) / l`` with ``l = |x_i - x_j|``,
        and the opposite force on ``j``.
    """
    # BEGIN SOLUTION
    i, j = springs[:, 0], springs[:, 1]
    d = x[i] - x[j]
    length = np.linalg.norm(d, axis=1)
    pair = (stiffness * (rest_length - length) / length)[:, None] * d
    f = np.zeros_like(x, dtype=float)
    np.add.at(f, i, pair)
    np.add.at(f, j, -pair)
    return f
    # END SOLUTION


def spring_jacobian(x, springs, stiffness, rest_length):
    """Jacobian ``df/dx`` of :func:`spring_forces`, dense.

    Parameters
    ----------
    x, springs, stiffness, rest_length : as in :func:`spring_forces`

    Returns
    -------
    K : ndarray, shape (n_particles * dim, n_particles * dim)
        ``K[i*dim + a, j*dim + b] = d f_{i,a} / d x_{j,b}``.
    """
    # BEGIN SOLUTION
    n, dim = x.shape
    K = np.zeros((n * dim, n * dim))
    eye = np.eye(dim)
    for (i, j), k, rest in zip(springs, stiffness, rest_length, strict=True):
        d = x[i] - x[j]
        length = np.linalg.norm(d)
        u = d / length
        uu = np.outer(u, u)
        block = -k * (uu + (1.0 - rest / length) * (eye - uu))
        si, sj = slice(i * dim, (i + 1) * dim), slice(j * dim, (j + 1) * dim)
        K[si, si] += block
        K[sj, sj] += block
        K[si, sj] -= block
        K[sj, si] -= block
    return K
    # END SOLUTION
