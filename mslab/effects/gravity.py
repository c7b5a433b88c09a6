"""Gravity: a constant acceleration g on every particle (lecture notes, §2.1).

"Down" has one rule everywhere: -y in 2D, -z in 3D (-x in 1D). A number ``g`` (TOML
``g = 9.81`` or ``SceneBuilder.add_gravity(9.81)``) pulls down with that strength; a
vector gives the acceleration itself.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.effects.base import BuildContext, Builder, Effect
from mslab.effects.registry import register
from mslab.effects.schema import Key
from mslab.lanes import state_sums

if TYPE_CHECKING:
    import numpy.typing as npt
    import scipy.sparse as sp


def down(dim: int) -> np.ndarray:
    """Return the unit vector pointing down: -y in 2D, -z in 3D, -x in 1D."""
    e = np.zeros(dim)
    e[dim - 1] = -1.0
    return e


def gravity_vector(g: npt.ArrayLike, dim: int) -> np.ndarray:
    """Return a gravity vector from a number (strength, pointing :func:`down`) or a vector."""
    arr = np.asarray(g, dtype=float)
    return float(arr) * down(dim) if arr.ndim == 0 else arr.reshape(dim)


def gravity_kernel(x: np.ndarray, v: np.ndarray, f: np.ndarray, f_gravity: np.ndarray) -> float:
    """Compiled-style kernel: ``f += m g`` (``f_gravity`` precomputed, (n, dim)); no power."""
    n, dim = f.shape
    for p in range(n):
        for c in range(dim):
            f[p, c] += f_gravity[p, c]
    return 0.0


@register
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
    section = "gravity"
    keys = (
        Key("g", "number|vector", unit="m/s^2",
            doc="a number pulls down (-y in 2D, -z in 3D, -x in 1D) with that strength; "
                "a vector is g itself"),
    )
    builder_methods = ("add_gravity",)
    unique = True
    order = 20
    summary = "uniform gravity `f = m g` on every particle"
    kernel = staticmethod(gravity_kernel)

    def __init__(self, g: npt.ArrayLike, mass: np.ndarray):
        self.g = np.asarray(g, dtype=float)
        self.mass = np.asarray(mass, dtype=float)
        self._f = np.ascontiguousarray(self.mass[:, None] * self.g[None, :])

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return ``m_i g`` for every particle, shape (n_particles, dim)."""
        return self._f.copy()

    def releasable_energy(self, movable: np.ndarray, height: float) -> float:
        """Return the energy this field can release on the ``movable`` particles over ``height``.

        Capability read by the blow-up checks' energy scale (:mod:`mslab.ledger`):
        ``sum_movable m |g| height``.
        """
        return float(np.sum(self.mass[movable]) * np.linalg.norm(self.g)) * height

    def energy(self, x: np.ndarray) -> float:
        """Return the potential energy ``-sum_i m_i g . x_i``."""
        return float(-np.sum(self._f * x))

    def energies(self, xs: np.ndarray) -> np.ndarray:
        """:meth:`energy` of each state of ``xs`` (k, n, dim), bitwise (one numpy sum per state)."""
        if type(self).energy is not Gravity.energy:  # a subclass's own energy, state by state
            return super().energies(xs)
        return -state_sums(self._f * xs)

    def jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[sp.spmatrix | None, sp.spmatrix | None]:
        """Return ``(None, None)``: a constant force has zero Jacobians."""
        return None, None

    def constant_force(self) -> np.ndarray:
        """Return ``m_i g`` for every particle, shape (n_particles, dim) (capability: a constant force)."""
        return self._f.copy()

    def kernel_params(self) -> tuple:
        """Return ``(m g,)``, shape (n_particles, dim), for :func:`gravity_kernel`."""
        return (self._f,)

    @staticmethod
    def add_gravity(builder: Builder, g: npt.ArrayLike) -> None:
        """Add uniform gravity: a vector (``[0, -9.81]``) or a number pulling down (-y in 2D, -z in 3D)."""
        builder.add_effect(Gravity, g=g)

    @classmethod
    def create(cls, values: dict, ctx: BuildContext) -> Gravity:
        """Return the gravity of the checked values on the scene's masses."""
        return cls(gravity_vector(values["g"], ctx.dim), ctx.mass)

    @classmethod
    def example(cls, dim: int) -> dict:
        """Return ``g = 9.81`` (pulling down) for the registry-wide tests."""
        return {"g": 9.81}

    def __repr__(self):
        return f"Gravity(g={self.g.tolist()})"
