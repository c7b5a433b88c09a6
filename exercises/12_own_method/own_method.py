"""Exercise 12: a third-order Runge-Kutta method of your own (lesson 10; eqs. 16-20 of the lecture notes)."""

import numpy as np


def order3_conditions(A, b):
    """Residuals of the four order-3 conditions of the tableau ``(A, b)``.

    ``[sum(b) - 1, b.c - 1/2, b.c^2 - 1/3, b.(A c) - 1/6]`` with ``c = A 1``.

    Parameters
    ----------
    A : ndarray, shape (s, s)
    b : ndarray, shape (s,)

    Returns
    -------
    residuals : ndarray, shape (4,)
    """
    # BEGIN SOLUTION
    A, b = np.asarray(A, dtype=float), np.asarray(b, dtype=float)
    c = A.sum(axis=1)
    return np.array([b.sum() - 1.0, b @ c - 0.5, b @ c**2 - 1.0 / 3.0, b @ (A @ c) - 1.0 / 6.0])
    # END SOLUTION


def kutta_family(c2, c3):
    """The three-stage explicit method of order 3 with nodes ``(0, c2, c3)``.

    Returns
    -------
    A : ndarray, shape (3, 3)
        Strictly lower triangular.
    b : ndarray, shape (3,)
    """
    # BEGIN SOLUTION
    b2 = (3.0 * c3 - 2.0) / (6.0 * c2 * (c3 - c2))
    b3 = (2.0 - 3.0 * c2) / (6.0 * c3 * (c3 - c2))
    b1 = 1.0 - b2 - b3
    a32 = 1.0 / (6.0 * c2 * b3)
    A = np.array([[0.0, 0.0, 0.0], [c2, 0.0, 0.0], [c3 - a32, a32, 0.0]])
    return A, np.array([b1, b2, b3])
    # END SOLUTION


def my_method():
    """Your own three-stage explicit method of order 3.

    Returns
    -------
    A : ndarray, shape (3, 3)
    b : ndarray, shape (3,)
    """
    # BEGIN SOLUTION
    return kutta_family(0.4, 0.9)
    # END SOLUTION


def rk3_step(x, v, accel, dt, A, b):
    """One explicit Runge-Kutta step of the tableau ``(A, b)`` on ``x' = v, v' = accel(x, v)``.

    Parameters
    ----------
    x, v : ndarray, shape (n_particles, dim)
    accel : callable, ``accel(x, v) -> a``
    dt : float
    A : ndarray, shape (s, s), strictly lower triangular
    b : ndarray, shape (s,)

    Returns
    -------
    x_new, v_new : ndarray, shape (n_particles, dim)
    """
    # BEGIN SOLUTION
    A, b = np.asarray(A, dtype=float), np.asarray(b, dtype=float)
    kx, kv = [], []
    for i in range(len(b)):
        xi = x + dt * sum(A[i, j] * kx[j] for j in range(i))
        vi = v + dt * sum(A[i, j] * kv[j] for j in range(i))
        kx.append(vi)
        kv.append(accel(xi, vi))
    x_new = x + dt * sum(bi * k for bi, k in zip(b, kx, strict=True))
    v_new = v + dt * sum(bi * k for bi, k in zip(b, kv, strict=True))
    return x_new, v_new
    # END SOLUTION
