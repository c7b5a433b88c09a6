"""Wind: viscous drag relative to a moving air mass, ``f_i = -c (v_i - w)``.

Air drag of the course (§2.5 of the lecture notes, ``f = -gamma v``) measured against air that moves
with a constant velocity ``w`` instead of still air. Its power splits into two parts::

    f . v = -c |v|^2 + c w . v
          = -(dissipated power P_D)  +  (external power P_W)

``P_D = c sum_i |v_i|^2 >= 0`` is booked in the ledger's ``dissipated`` column like any
drag; ``P_W`` is the work the wind's drive puts in. The drive ``c w`` is a constant force,
so its work is ``W_ext = c w . sum_i (x_i - x_i(0))`` exactly, and the ledger
``K + U + D - W_ext`` is constant for the exact motion (:class:`mslab.trajectory.Energy`).
A particle alone in the wind (mass m, no other force) relaxes to the wind's velocity::

    v(t) = w + (v0 - w) exp(-c t / m).

Jacobians: ``df/dx = 0``, ``df/dv = -c I`` (implicit methods treat it like damping).
Scene files: ``[wind]`` with ``velocity`` and ``drag``; Python: ``SceneBuilder.add_wind``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.effects.base import BuildContext, Builder, Effect
from mslab.effects.registry import register
from mslab.effects.schema import Key

if TYPE_CHECKING:
    import numpy.typing as npt
    import scipy.sparse as sp


def wind_kernel(x: np.ndarray, v: np.ndarray, f: np.ndarray, drag: float, velocity: np.ndarray) -> float:
    """Compiled-style kernel: ``f += -c (v - w)``; return the dissipated power ``c |v|^2``."""
    n, dim = f.shape
    power = 0.0
    for p in range(n):
        for c in range(dim):
            f[p, c] -= drag * (v[p, c] - velocity[c])
            power += drag * v[p, c] * v[p, c]
    return power


@register
class Wind(Effect):
    """Drag towards a constant wind velocity on every particle.

    Force ``f_i = -c (v_i - w)``; dissipated power ``P_D = c sum_i |v_i|^2``; external
    power put in by the wind ``P_W = c w . sum_i v_i``, external work since ``x0``
    ``W_ext = c w . sum_i (x_i - x0_i)``; ``df/dx = 0``, ``df/dv = -c I``.

    Parameters
    ----------
    velocity : array_like, shape (dim,)
        Wind velocity w (m/s).
    drag : float
        Drag coefficient c (force per relative velocity, kg/s).
    n_particles : int
    """

    name = "wind"
    section = "wind"
    keys = (
        Key("velocity", "vector", unit="m/s", doc="wind velocity w: the air moves with it"),
        Key("drag", low=0.0, unit="kg/s", doc="drag coefficient c: f = -c (v - w); 0 builds nothing"),
    )
    builder_methods = ("add_wind",)
    unique = True
    order = 32
    summary = "drag in a wind `f = -c (v - w)`; the wind's work `c w . v` is the ledger's `external` column"
    kernel = staticmethod(wind_kernel)
    velocity_dependent = True
    dissipative = True
    conservative = False
    driving = True

    def __init__(self, velocity: npt.ArrayLike, drag: float, n_particles: int):
        self.velocity = np.ascontiguousarray(velocity, dtype=float).reshape(-1)
        self.drag = float(drag)
        self.n = int(n_particles)

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return ``-c (v - w)``, shape (n_particles, dim)."""
        return -self.drag * (v - self.velocity)

    def force_and_power(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Return the force ``-c (v - w)`` and the dissipated power ``c sum_i |v_i|^2``."""
        return self.force(x, v), self.power(x, v)

    def power(self, x: np.ndarray, v: np.ndarray) -> float:
        """Return the dissipated power ``c sum_i |v_i|^2`` (>= 0)."""
        return self.drag * float(np.sum(v * v))

    def external_power(self, x: np.ndarray, v: np.ndarray) -> float:
        """Return the power the wind puts in, ``c w . sum_i v_i``."""
        return self.drag * float(np.sum(v @ self.velocity))

    def external_work(self, x: np.ndarray, x0: np.ndarray) -> float:
        """Return the wind's work since ``x0``, ``c w . sum_i (x_i - x0_i)``."""
        return self.drag * float(np.sum((x - x0) @ self.velocity))

    def jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[None, sp.csr_matrix]:
        """Return ``(None, -c I)``."""
        import scipy.sparse as sp  # on first use: `import mslab` stays cheap

        size = self.n * self.velocity.size
        return None, -self.drag * sp.identity(size, format="csr")

    def kernel_params(self) -> tuple:
        """Return ``(drag, velocity)`` for :func:`wind_kernel`."""
        return (self.drag, self.velocity)

    def kernel_items(self, n_particles: int) -> int:
        """Return ``n_particles``: the kernel visits every particle."""
        return n_particles

    @staticmethod
    def add_wind(builder: Builder, velocity: npt.ArrayLike, drag: float) -> None:
        """Add drag ``f = -drag (v - velocity)`` in a constant wind on every particle (``drag = 0``: none)."""
        builder.add_effect(Wind, velocity=velocity, drag=drag)

    @classmethod
    def create(cls, values: dict, ctx: BuildContext) -> Wind | None:
        """Return the wind of the checked values, or None when ``drag = 0``."""
        return cls(values["velocity"], values["drag"], ctx.n_particles) if values["drag"] > 0 else None

    @classmethod
    def example(cls, dim: int) -> dict:
        """Return a wind of ``[1.5, -0.5, 0.8][:dim]`` m/s with ``drag = 0.6`` for the registry-wide tests."""
        return {"velocity": [1.5, -0.5, 0.8][:dim], "drag": 0.6}

    def __repr__(self):
        return f"Wind(velocity={self.velocity.tolist()}, drag={self.drag})"
