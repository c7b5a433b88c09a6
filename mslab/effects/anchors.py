"""Anchor springs: chosen particles pulled towards fixed points by zero-length springs.

A soft alternative to pinning: particle ``p`` is tied to the point ``a`` (by default where it
starts) by a spring of stiffness ``k`` and rest length 0::

    f_p = -k (x_p - a),      U = k |x_p - a|^2 / 2,      df_p/dx_p = -k I.

The force is external (the anchor points do not move), so momentum is not conserved;
energy is (the effect is conservative). Scene files: ``[anchors]`` with ``particles``,
``stiffness`` and optionally ``points``; Python: ``SceneBuilder.add_anchors``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.effects.base import BuildContext, Builder, Effect, block_diagonal
from mslab.effects.registry import register
from mslab.effects.schema import Key

if TYPE_CHECKING:
    import numpy.typing as npt
    import scipy.sparse as sp


def anchor_kernel(x: np.ndarray, v: np.ndarray, f: np.ndarray, particles: np.ndarray, points: np.ndarray,
                  stiffness: np.ndarray) -> float:
    """Compiled-style kernel: ``f[p] -= k (x[p] - a)`` for every anchor; no power."""
    dim = x.shape[1]
    for q in range(particles.shape[0]):
        p = particles[q]
        for c in range(dim):
            f[p, c] -= stiffness[q] * (x[p, c] - points[q, c])
    return 0.0


@register
class Anchors(Effect):
    """Zero-length springs from particles to fixed points.

    Parameters
    ----------
    particles : ndarray of int, shape (m,)
        The anchored particles (a particle may appear more than once).
    points : ndarray, shape (m, dim)
        The fixed points.
    stiffness : ndarray, shape (m,)
    n_particles : int
    """

    name = "anchors"
    section = "anchors"
    keys = (
        Key("particles", "indices", doc="the anchored particles"),
        Key("stiffness", "numbers", low=0.0, per="particles", unit="N/m",
            doc="stiffness of each anchor spring (one, or one per particle)"),
        Key("points", "vectors", default=None, per="particles", unit="m",
            default_doc="the initial positions", doc="where each particle is pulled to"),
    )
    builder_methods = ("add_anchors",)
    order = 35
    summary = "zero-length springs pulling chosen particles to fixed points"
    kernel = staticmethod(anchor_kernel)

    def __init__(self, particles: npt.ArrayLike, points: npt.ArrayLike, stiffness: npt.ArrayLike,
                 n_particles: int):
        self.particles = np.ascontiguousarray(particles, dtype=np.int64).reshape(-1)
        self.points = np.ascontiguousarray(points, dtype=float).reshape(self.particles.size, -1)
        self.stiffness = np.ascontiguousarray(np.broadcast_to(stiffness, self.particles.shape), dtype=float)
        self.n = int(n_particles)

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return ``-k (x_p - a)`` on the anchored particles, zero elsewhere; shape (n_particles, dim)."""
        f = np.zeros_like(x)
        np.add.at(f, self.particles, -self.stiffness[:, None] * (x[self.particles] - self.points))
        return f

    def energy(self, x: np.ndarray) -> float:
        """Return ``sum k |x_p - a|^2 / 2``."""
        d = x[self.particles] - self.points
        return float(0.5 * np.sum(self.stiffness * np.einsum("ij,ij->i", d, d)))

    def jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[sp.csr_matrix, None]:
        """Return ``(df/dx, None)`` with ``-k I`` blocks on the anchored particles."""
        dim = x.shape[1]
        blocks = -self.stiffness[:, None, None] * np.eye(dim)[None]
        return block_diagonal(blocks, self.particles, self.n), None

    def kernel_params(self) -> tuple:
        """Return ``(particles, points, stiffness)`` for :func:`anchor_kernel`."""
        return (self.particles, self.points, self.stiffness)

    @staticmethod
    def add_anchors(builder: Builder, particles: npt.ArrayLike, stiffness: npt.ArrayLike,
                    points: npt.ArrayLike | None = None) -> None:
        """Pull ``particles`` towards ``points`` (default: where they are now) by springs of ``stiffness``.

        ``stiffness``: one number, or one per particle; ``points``: one vector per particle.
        """
        builder.add_effect(Anchors, particles=particles, stiffness=stiffness, points=points)

    @classmethod
    def add(cls, builder: Builder, values: dict, prefix: str = "") -> None:
        """Record the anchors; absent ``points`` become the particles' current positions."""
        if values["points"] is None:  # the particles' positions when the anchors are added
            values = {**values, "points": builder.positions()[values["particles"]]}
        super().add(builder, values, prefix)

    @classmethod
    def build(cls, entries: list, ctx: BuildContext) -> list[Effect]:
        """All anchor sets of the scene as one effect."""
        particles, points, stiffness = (np.concatenate([np.asarray(e[k]) for e in entries])
                                        for k in ("particles", "points", "stiffness"))
        return [cls(particles, points, stiffness, ctx.n_particles)]

    @classmethod
    def example(cls, dim: int) -> dict:
        """Return three anchors for the registry-wide tests."""
        return {"particles": [0, 2, 5], "stiffness": [30.0, 50.0, 80.0],
                "points": [[0.2] * dim, [-0.5] * dim, [0.0] * dim]}

    def __repr__(self):
        return f"Anchors(n_anchors={self.particles.size})"
