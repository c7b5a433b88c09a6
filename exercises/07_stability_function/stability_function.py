"""Exercise 07: the stability function of a tableau and its real interval (lecture notes, eqs. 29-33)."""

import numpy as np


def stability_function(A, b, z):
    """``R(z)`` of the Runge-Kutta method ``(A, b)``: one step on ``y' = lam y`` is ``y_1 = R(h lam) y_0``.

    ``R(z) = 1 + z b^T (I - z A)^{-1} 1``.

    Parameters
    ----------
    A : ndarray, shape (s, s)
    b : ndarray, shape (s,)
    z : complex or ndarray of complex, any shape

    Returns
    -------
    R : ndarray of complex, same shape as ``z``
    """
    # BEGIN SOLUTION
    A, b = np.asarray(A, dtype=float), np.asarray(b, dtype=float)
    z = np.asarray(z, dtype=complex)
    s = len(b)
    R = np.empty(z.shape, dtype=complex)
    for idx in np.ndindex(*z.shape):
        stages = np.linalg.solve(np.eye(s) - z[idx] * A, np.ones(s))
        R[idx] = 1.0 + z[idx] * (b @ stages)
    return R
    # END SOLUTION


def real_stability_interval(A, b, tol=1e-12):
    """Left end ``a < 0`` of the real stability interval ``[a, 0]`` found by bisection.

    ``a`` is the point where ``|R(x)|`` first exceeds 1 when ``x`` walks left from 0.
    Bracket it (double a trial point ``x = -1, -2, -4, ...`` until ``|R(x)| > 1``, at most
    up to ``x = -1e6``), then bisect until the bracket is shorter than ``tol``. (For the
    methods here ``|R| <= 1`` holds on the whole of ``[a, 0]``.)

    Parameters
    ----------
    A : ndarray, shape (s, s)
    b : ndarray, shape (s,)
    tol : float

    Returns
    -------
    a : float
    """
    # BEGIN SOLUTION
    def unstable(x):
        return abs(stability_function(A, b, x)) > 1.0

    lo = -1.0
    while not unstable(lo):
        lo *= 2.0
        if lo < -1e6:
            return -np.inf
    hi = lo / 2.0 if lo < -1.0 else 0.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if unstable(mid):
            lo = mid
        else:
            hi = mid
    return float(0.5 * (lo + hi))
    # END SOLUTION
