"""Exercise 02: forward Euler and the two symplectic Euler steps (lecture notes, eqs. 6-10)."""


def forward_euler_step(x, v, accel, dt):
    """One forward (explicit) Euler step.

    Parameters
    ----------
    x, v : ndarray, shape (n_particles, dim)
        Positions and velocities at time t.
    accel : callable
        ``accel(x, v) -> a``, the acceleration, shape (n_particles, dim).
    dt : float
        Step size h.

    Returns
    -------
    x_new, v_new : ndarray, shape (n_particles, dim)
        Both updated from the *old* state only.
    """
    # BEGIN SOLUTION
    a = accel(x, v)
    return x + dt * v, v + dt * a
    # END SOLUTION


def symplectic_euler_step(x, v, accel, dt):
    """Symplectic Euler, velocity first (lecture notes, eqs. 9-10).

    The velocity is updated with the acceleration at the old state; the position then
    moves with the *new* velocity. Returns ``(x_new, v_new)``, shapes as ``x``.
    """
    # BEGIN SOLUTION
    v_new = v + dt * accel(x, v)
    return x + dt * v_new, v_new
    # END SOLUTION


def symplectic_euler_x_step(x, v, accel, dt):
    """Symplectic Euler, position first (lecture notes, eqs. 7-8).

    The position moves with the old velocity; the velocity is then updated with the
    acceleration at the *new* position and the old velocity. Returns ``(x_new, v_new)``.
    """
    # BEGIN SOLUTION
    x_new = x + dt * v
    return x_new, v + dt * accel(x_new, v)
    # END SOLUTION
