"""Exercise 03: Heun's method and the explicit midpoint method (lecture notes, eqs. 11-15)."""


def heun_step(x, v, accel, dt):
    """One step of Heun's method for ``x' = v, v' = a(x, v)``.

    Predict the end of the step with an Euler step, then advance with the average of the
    slopes at the start and at the predicted end.

    Parameters
    ----------
    x, v : ndarray, shape (n_particles, dim)
    accel : callable, ``accel(x, v) -> a`` of shape (n_particles, dim)
    dt : float

    Returns
    -------
    x_new, v_new : ndarray, shape (n_particles, dim)
    """
    # BEGIN SOLUTION
    a = accel(x, v)
    x_pred, v_pred = x + dt * v, v + dt * a
    a_pred = accel(x_pred, v_pred)
    return x + 0.5 * dt * (v + v_pred), v + 0.5 * dt * (a + a_pred)
    # END SOLUTION


def midpoint_step(x, v, accel, dt):
    """One step of the explicit midpoint method.

    Take half an Euler step to the middle of the interval, then the whole step with the
    slope (velocity *and* acceleration) found there. Returns ``(x_new, v_new)``.
    """
    # BEGIN SOLUTION
    a = accel(x, v)
    x_mid, v_mid = x + 0.5 * dt * v, v + 0.5 * dt * a
    return x + dt * v_mid, v + dt * accel(x_mid, v_mid)
    # END SOLUTION
