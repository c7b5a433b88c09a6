"""Gravity: a constant acceleration g on every particle (seed section 2.1)."""

from __future__ import annotations

import numpy as np

from mslab.effects.base import Effect


class Gravity(Effect):
    """Uniform gravity ``f_i = m_i g``.

    Potential energy ``U = -sum_i m_i g . x_i`` (height times weight); Jacobians are zero.

    Parameters
    ----------
    g : array_like, shape (dim,)
        Gravitational acceleration, e.g. ``[0, -9.81]``.
    mass : ndarray, shape (n_particles,)
    """

    name = "gravity"

    def __init__(self, g, mass: np.ndarray):
        self.g = np.asarray(g, dtype=float)
        self.mass = np.asarray(mass, dtype=float)
        self._f = self.mass[:, None] * self.g[None, :]

    def force(self, x, v):
        return self._f.copy()

    def energy(self, x):
        return float(-np.sum(self._f * x))

    def jacobians(self, x, v):
        return None, None

    def __repr__(self):
        return f"Gravity(g={self.g.tolist()})"
