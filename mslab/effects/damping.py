"""Viscous damping (air drag): ``f_i = -gamma v_i`` (seed section 2.5, a = (f - γv)/m)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from mslab.effects.base import Effect


class Damping(Effect):
    """Viscous drag proportional to velocity.

    Force ``f_i = -gamma v_i``; dissipated power ``P = gamma sum_i |v_i|^2``;
    ``df/dx = 0``, ``df/dv = -gamma I``.

    Parameters
    ----------
    gamma : float
        Damping coefficient (force per velocity, kg/s), the γ of the course.
    n_particles, dim : int
    """

    name = "damping"
    velocity_dependent = True
    dissipative = True
    conservative = False

    def __init__(self, gamma: float, n_particles: int, dim: int):
        self.gamma = float(gamma)
        self.n = n_particles
        self.dim = dim

    def force(self, x, v):
        return -self.gamma * v

    def force_and_power(self, x, v):
        return -self.gamma * v, self.gamma * float(np.sum(v * v))

    def power(self, x, v):
        return self.gamma * float(np.sum(v * v))

    def jacobians(self, x, v):
        return None, -self.gamma * sp.identity(self.n * self.dim, format="csr")

    def __repr__(self):
        return f"Damping(gamma={self.gamma})"
