"""Exercise 08: a penalty force against a plane, with regularised Coulomb friction (lecture notes, §2.7)."""

import numpy as np


def penetration_depth(x, normal, offset):
    """How deep each particle is below the plane ``n . x = offset``.

    Parameters
    ----------
    x : ndarray, shape (n_particles, dim)
    normal : ndarray, shape (dim,)
        Unit normal pointing to the free side.
    offset : float

    Returns
    -------
    depth : ndarray, shape (n_particles,)
        ``offset - n . x``: positive inside the wall, negative outside.
    """
    # BEGIN SOLUTION
    return offset - x @ normal
    # END SOLUTION


def plane_contact_force(x, v, normal, offset, stiffness, friction, slip_velocity):
    """Penalty force with friction on every particle.

    A particle with depth ``p > 0`` is pushed out along the normal by ``f_n = k p n``.
    Friction opposes the tangential velocity ``v_t = v - (n . v) n`` with
    ``f_t = -mu |f_n| v_t / sqrt(|v_t|^2 + eps^2)`` (``eps`` = ``slip_velocity``).
    Particles outside (``p <= 0``) feel nothing.

    Parameters
    ----------
    x, v : ndarray, shape (n_particles, dim)
    normal : ndarray, shape (dim,), unit length
    offset, stiffness, friction, slip_velocity : float

    Returns
    -------
    f : ndarray, shape (n_particles, dim)
    """
    # BEGIN SOLUTION
    depth = penetration_depth(x, normal, offset)
    active = depth > 0.0
    fn = np.where(active, stiffness * depth, 0.0)
    vt = v - (v @ normal)[:, None] * normal[None, :]
    speed = np.sqrt(np.sum(vt * vt, axis=1) + slip_velocity**2)
    ft = -(friction * fn / speed)[:, None] * vt
    return fn[:, None] * normal[None, :] + ft
    # END SOLUTION
