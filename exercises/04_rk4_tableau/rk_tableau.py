"""Exercise 04: a Runge-Kutta stepper driven by a Butcher tableau; RK4 (lecture notes, eqs. 16-20)."""

import numpy as np


def rk4_tableau():
    """The classical RK4 method as a Butcher tableau.

    Returns
    -------
    A : ndarray, shape (4, 4)
        Stage coefficients, strictly lower triangular.
    b : ndarray, shape (4,)
        Weights.
    c : ndarray, shape (4,)
        Nodes (row sums of A).
    """
    # BEGIN SOLUTION
    A = np.zeros((4, 4))
    A[1, 0] = A[2, 1] = 0.5
    A[3, 2] = 1.0
    b = np.array([1.0, 2.0, 2.0, 1.0]) / 6.0
    return A, b, A.sum(axis=1)
    # END SOLUTION


def rk_step(x, v, accel, dt, A, b):
    """One step of the explicit Runge-Kutta method ``(A, b)`` for ``x' = v, v' = a(x, v)``.

    With ``y = (x, v)`` and ``F(y) = (v, a(x, v))``, stage ``i`` is
    ``K_i = F(y_n + dt * sum_{j<i} A[i, j] K_j)`` and the step is
    ``y_{n+1} = y_n + dt * sum_i b[i] K_i``.

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
        Exactly ``s`` calls of ``accel`` per step.
    """
    # BEGIN SOLUTION
    A, b = np.asarray(A, dtype=float), np.asarray(b, dtype=float)
    kx, kv = [], []
    for i in range(len(b)):
        xi = x + dt * sum((A[i, j] * kx[j] for j in range(i)), np.zeros_like(x))
        vi = v + dt * sum((A[i, j] * kv[j] for j in range(i)), np.zeros_like(v))
        kx.append(vi)
        kv.append(accel(xi, vi))
    x_new = x + dt * sum(bi * k for bi, k in zip(b, kx, strict=True))
    v_new = v + dt * sum(bi * k for bi, k in zip(b, kv, strict=True))
    return x_new, v_new
    # END SOLUTION
