"""Reference kernels of the benchmark (``mslab bench``): what a hand-written compiled code does.

These are *not* used by mslab's simulations. They are the yardstick: a plain numba loop of
classical RK4 for springs + gravity (the "write it yourself in a compiled language"
baseline) and a single-thread spring-force kernel. ``mslab bench`` reports mslab's
times as ratios to these, measured in the same run.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def ref_acceleration(x, v, inv_mass, i, j, stiffness, rest_length, g, a):
    """``a = M^-1 (sum of Hooke spring forces) + g`` for free particles (inv_mass > 0)."""
    n, dim = x.shape
    ref_spring_force(x, i, j, stiffness, rest_length, a)
    for p in range(n):
        if inv_mass[p] > 0.0:
            for c in range(dim):
                a[p, c] = inv_mass[p] * a[p, c] + g[c]
        else:
            for c in range(dim):
                a[p, c] = 0.0


@njit(cache=True)
def ref_rk4(x, v, inv_mass, i, j, stiffness, rest_length, g, dt, n_steps):
    """``n_steps`` of classical RK4 (3D springs + gravity), in place on ``x, v``."""
    n, dim = x.shape
    k1x = np.empty((n, dim))
    k2x = np.empty((n, dim))
    k3x = np.empty((n, dim))
    k4x = np.empty((n, dim))
    k1v = np.empty((n, dim))
    k2v = np.empty((n, dim))
    k3v = np.empty((n, dim))
    k4v = np.empty((n, dim))
    xt = np.empty((n, dim))
    vt = np.empty((n, dim))
    for _ in range(n_steps):
        k1x[:, :] = v
        ref_acceleration(x, v, inv_mass, i, j, stiffness, rest_length, g, k1v)
        for p in range(n):
            for c in range(dim):
                xt[p, c] = x[p, c] + 0.5 * dt * k1x[p, c]
                vt[p, c] = v[p, c] + 0.5 * dt * k1v[p, c]
        k2x[:, :] = vt
        ref_acceleration(xt, vt, inv_mass, i, j, stiffness, rest_length, g, k2v)
        for p in range(n):
            for c in range(dim):
                xt[p, c] = x[p, c] + 0.5 * dt * k2x[p, c]
                vt[p, c] = v[p, c] + 0.5 * dt * k2v[p, c]
        k3x[:, :] = vt
        ref_acceleration(xt, vt, inv_mass, i, j, stiffness, rest_length, g, k3v)
        for p in range(n):
            for c in range(dim):
                xt[p, c] = x[p, c] + dt * k3x[p, c]
                vt[p, c] = v[p, c] + dt * k3v[p, c]
        k4x[:, :] = vt
        ref_acceleration(xt, vt, inv_mass, i, j, stiffness, rest_length, g, k4v)
        for p in range(n):
            for c in range(dim):
                x[p, c] += dt / 6.0 * (k1x[p, c] + 2.0 * k2x[p, c] + 2.0 * k3x[p, c] + k4x[p, c])
                v[p, c] += dt / 6.0 * (k1v[p, c] + 2.0 * k2v[p, c] + 2.0 * k3v[p, c] + k4v[p, c])


@njit(cache=True)
def ref_spring_force(x, i, j, stiffness, rest_length, f):
    """Hooke spring forces (3D) into the preallocated ``f``: one pass over the springs."""
    f[:, :] = 0.0
    for q in range(i.shape[0]):
        p, r = i[q], j[q]
        dx = x[p, 0] - x[r, 0]
        dy = x[p, 1] - x[r, 1]
        dz = x[p, 2] - x[r, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        s = -stiffness[q] * (1.0 - rest_length[q] / length)
        f[p, 0] += s * dx
        f[p, 1] += s * dy
        f[p, 2] += s * dz
        f[r, 0] -= s * dx
        f[r, 1] -= s * dy
        f[r, 2] -= s * dz
