"""Exercise 05: position Verlet and leapfrog, with their start-up steps (lecture notes, eqs. 21-26).

Forces here depend on positions only: call ``accel(x)``.
"""


def verlet_start(x0, v0, accel, dt):
    """The fictitious previous position ``x_{-1}`` that starts Verlet.

    Expand ``x(t - h)`` in a Taylor series around t = 0 up to the ``h^2`` term, with
    ``x'(0) = v0`` and ``x''(0) = accel(x0)``.

    Parameters
    ----------
    x0, v0 : ndarray, shape (n_particles, dim)
    accel : callable, ``accel(x) -> a``
    dt : float

    Returns
    -------
    x_prev : ndarray, shape (n_particles, dim)
    """
    # BEGIN SOLUTION
    return x0 - dt * v0 + 0.5 * dt * dt * accel(x0)
    # END SOLUTION


def verlet_step(x, x_prev, accel, dt):
    """One position-Verlet step: ``x_{n+1}`` from ``x_n`` and ``x_{n-1}`` (lecture notes, eq. 23).

    Returns
    -------
    x_next : ndarray, shape (n_particles, dim)
    """
    # BEGIN SOLUTION
    return 2.0 * x - x_prev + dt * dt * accel(x)
    # END SOLUTION


def leapfrog_start(x0, v0, accel, dt):
    """The staggered velocity ``v_{1/2}`` that starts leapfrog: half an Euler step.

    Returns
    -------
    v_half : ndarray, shape (n_particles, dim)
    """
    # BEGIN SOLUTION
    return v0 + 0.5 * dt * accel(x0)
    # END SOLUTION


def leapfrog_step(x, v_half, accel, dt):
    """One leapfrog step: the position jumps with the half-step velocity, then the velocity
    jumps over the new position with the acceleration there.

    Parameters
    ----------
    x : ndarray, shape (n_particles, dim)
        ``x_n``.
    v_half : ndarray, shape (n_particles, dim)
        ``v_{n+1/2}``.

    Returns
    -------
    x_next, v_half_next : ndarray, shape (n_particles, dim)
        ``x_{n+1}`` and ``v_{n+3/2}``.
    """
    # BEGIN SOLUTION
    x_next = x + dt * v_half
    return x_next, v_half + dt * accel(x_next)
    # END SOLUTION
