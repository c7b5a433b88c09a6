"""Exercise 06: implicit Euler by fixed-point iteration and by Newton's method (lecture notes, eqs. 27-28)."""

import numpy as np


def implicit_euler_fixed_point(x, v, accel, dt, tol=1e-10, max_iter=100):
    """One implicit Euler step, solved by fixed-point iteration (lecture notes, eq. 28).

    Unknowns ``(X, V)`` = the new state with ``X = x + dt V`` and ``V = v + dt accel(X, V)``.
    Start from ``(X, V) = (x, v)`` and repeat ``(X, V) <- (x + dt V, v + dt accel(X, V))``
    until neither ``X`` nor ``V`` changes by more than ``tol`` (max-norm) in one sweep.

    Parameters
    ----------
    x, v : ndarray, shape (n_particles, dim)
    accel : callable, ``accel(x, v) -> a``
    dt, tol : float
    max_iter : int

    Returns
    -------
    x_new, v_new : ndarray, shape (n_particles, dim)
    n_iter : int
        Sweeps made (calls of ``accel``).

    Raises
    ------
    RuntimeError
        If the iteration has not converged after ``max_iter`` sweeps or produces
        non-finite numbers (the map is no contraction: ``dt`` too large for the stiffness).
    """
    # BEGIN SOLUTION
    X, V = x, v
    for k in range(1, max_iter + 1):
        X_new, V_new = x + dt * V, v + dt * accel(X, V)
        if not (np.all(np.isfinite(X_new)) and np.all(np.isfinite(V_new))):
            break
        change = max(np.max(np.abs(X_new - X)), np.max(np.abs(V_new - V)))
        X, V = X_new, V_new
        if change <= tol:
            return X, V, k
    raise RuntimeError(f"fixed-point iteration did not converge (dt = {dt})")
    # END SOLUTION


def implicit_euler_newton(x, v, problem, dt, tol=1e-10, max_iter=20):
    """One implicit Euler step, solved by Newton's method on the new velocity.

    With ``X(V) = x + dt V`` the step asks for a root of
    ``g(V) = V - v - dt a(X(V), V)``. Newton's correction solves
    ``(I - dt (dt K + D)) dV = -g(V)`` with ``K = da/dx`` and ``D = da/dv`` taken at
    ``(X(V), V)`` (both from ``problem.jacobians``, flattened row-major:
    particle-major, then axis). Start from ``V = v``; stop when ``max|g(V)| <= tol``.

    Parameters
    ----------
    x, v : ndarray, shape (n_particles, dim)
    problem : object
        ``problem(x, v) -> a`` and ``problem.jacobians(x, v) -> (K, D)``, each
        (n_particles*dim, n_particles*dim).
    dt, tol : float
    max_iter : int

    Returns
    -------
    x_new, v_new : ndarray, shape (n_particles, dim)
    n_iter : int
        Newton corrections applied (0 if ``v`` already solves the step).

    Raises
    ------
    RuntimeError
        If ``max|g|`` is not below ``tol`` after ``max_iter`` corrections.
    """
    # BEGIN SOLUTION
    V = np.array(v, dtype=float)
    eye = np.eye(V.size)
    for k in range(max_iter + 1):
        X = x + dt * V
        g = V - v - dt * problem(X, V)
        if np.max(np.abs(g)) <= tol:
            return X, V, k
        if k == max_iter:
            break
        K, D = problem.jacobians(X, V)
        dV = np.linalg.solve(eye - dt * (dt * K + D), -g.ravel())
        V = V + dV.reshape(V.shape)
    raise RuntimeError(f"Newton's method did not converge in {max_iter} iterations")
    # END SOLUTION
