"""Viscous damping (air drag): ``f_i = -gamma v_i`` (§2.5 of the lecture notes, a = (f - γv)/m)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.effects.base import BuildContext, Builder, Effect
from mslab.effects.registry import register
from mslab.effects.schema import Key

if TYPE_CHECKING:
    import scipy.sparse as sp


def damping_kernel(x: np.ndarray, v: np.ndarray, f: np.ndarray, gamma: float) -> float:
    """Compiled-style kernel: ``f -= gamma v``; return the power ``gamma |v|^2``."""
    n, dim = f.shape
    power = 0.0
    for p in range(n):
        for c in range(dim):
            f[p, c] -= gamma * v[p, c]
            power += gamma * v[p, c] * v[p, c]
    return power


@register
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
    section = "damping"
    keys = (Key("gamma", low=0.0, unit="kg/s", doc="drag coefficient: f = -gamma v; 0 builds nothing"),)
    builder_methods = ("add_damping",)
    unique = True
    order = 30
    summary = "viscous air drag `f = -gamma v` on every particle"
    kernel = staticmethod(damping_kernel)
    velocity_dependent = True
    dissipative = True
    conservative = False

    def __init__(self, gamma: float, n_particles: int, dim: int):
        self.gamma = float(gamma)
        self.n = n_particles
        self.dim = dim

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return ``-gamma v``, shape (n_particles, dim)."""
        return -self.gamma * v

    def force_and_power(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Return the force ``-gamma v`` and the power ``gamma sum_i |v_i|^2``."""
        return -self.gamma * v, self.gamma * float(np.sum(v * v))

    def power(self, x: np.ndarray, v: np.ndarray) -> float:
        """Return the dissipated power ``gamma sum_i |v_i|^2``."""
        return self.gamma * float(np.sum(v * v))

    def jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[None, sp.csr_matrix]:
        """Return ``(None, -gamma I)``."""
        import scipy.sparse as sp  # on first use: `import mslab` stays cheap

        return None, -self.gamma * sp.identity(self.n * self.dim, format="csr")

    def linear_drag(self) -> float:
        """Return ``gamma`` (capability: linear drag ``f = -gamma v``)."""
        return self.gamma

    def kernel_params(self) -> tuple:
        """Return ``(gamma,)`` for :func:`damping_kernel`."""
        return (self.gamma,)

    @staticmethod
    def add_damping(builder: Builder, gamma: float) -> None:
        """Add viscous drag ``f = -gamma v`` on every particle (``gamma = 0``: none)."""
        builder.add_effect(Damping, gamma=gamma)

    @classmethod
    def create(cls, values: dict, ctx: BuildContext) -> Damping | None:
        """Return the drag of the checked values, or None when ``gamma = 0``."""
        gamma = values["gamma"]
        return cls(gamma, ctx.n_particles, ctx.dim) if gamma > 0 else None

    @classmethod
    def example(cls, dim: int) -> dict:
        """Return ``gamma = 0.7`` for the registry-wide tests."""
        return {"gamma": 0.7}

    def __repr__(self):
        return f"Damping(gamma={self.gamma})"
