"""Penalty colliders: a plane and a sphere, with optional friction (lecture notes, §2.7).

A particle that penetrates a collider by a depth ``p > 0`` feels a spring pushing it
back along the surface normal ``n``: ``f_n = k p n`` with potential ``U = k p^2 / 2``.
Friction is regularised Coulomb friction opposing the tangential velocity
``v_t = v - (n . v) n``::

    f_t = -mu |f_n| v_t / sqrt(|v_t|^2 + eps^2)

which tends to the Coulomb law ``-mu |f_n| v_t/|v_t|`` for ``|v_t| >> eps`` and stays
smooth (and differentiable for Newton) at rest. It dissipates ``P = -f_t . v >= 0``.

Both geometries share one compiled kernel, :func:`penalty_kernel`, the force written once
more in the numba-compatible style of the other effects (the compiled loops of
:mod:`mslab.fast` call it; the tests hold it equal to the numpy code to 1e-12).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.effects.base import Ball, BuildContext, Builder, Effect, Halfspace, block_diagonal
from mslab.effects.registry import register
from mslab.effects.schema import Key
from mslab.errors import SceneError

if TYPE_CHECKING:
    import numpy.typing as npt
    import scipy.sparse as sp


def penalty_kernel(x: np.ndarray, v: np.ndarray, f: np.ndarray, sphere: int, point: np.ndarray, level: float,
                   stiffness: float, friction: float, slip_velocity: float) -> float:
    """Compiled-style kernel of a plane or sphere collider; return the power friction dissipates.

    ``sphere = 0``: the half-space ``point . x >= level`` (``point`` is the unit normal,
    ``level`` the offset); ``sphere = 1``: the ball of centre ``point`` and radius ``level``.
    Adds ``k p n`` and the regularised friction ``-mu k p v_t / sqrt(|v_t|^2 + eps^2)`` on
    every particle with depth ``p > 0``.
    """
    n, dim = x.shape
    normal = np.empty(dim)
    power = 0.0
    for q in range(n):
        if sphere:
            r2 = 0.0
            for c in range(dim):
                r2 += (x[q, c] - point[c]) * (x[q, c] - point[c])
            r = np.sqrt(r2)
            depth = level - r
            if depth <= 0.0:
                continue
            for c in range(dim):
                normal[c] = (x[q, c] - point[c]) / r if r > 0.0 else 0.0
        else:
            height = 0.0
            for c in range(dim):
                height += x[q, c] * point[c]
            depth = level - height
            if depth <= 0.0:
                continue
            for c in range(dim):
                normal[c] = point[c]
        fn = stiffness * depth
        for c in range(dim):
            f[q, c] += fn * normal[c]
        if friction > 0.0:
            nv = 0.0
            for c in range(dim):
                nv += normal[c] * v[q, c]
            vt2 = 0.0
            for c in range(dim):
                vt2 += (v[q, c] - nv * normal[c]) * (v[q, c] - nv * normal[c])
            scale = friction * fn / np.sqrt(vt2 + slip_velocity * slip_velocity)
            for c in range(dim):
                ft = -scale * (v[q, c] - nv * normal[c])
                f[q, c] += ft
                power -= ft * v[q, c]
    return power


#: keys every penalty collider shares (after its geometry)
PENALTY_KEYS = (
    Key("stiffness", low=0.0, strict=True, unit="N/m", doc="penalty stiffness k"),
    Key("friction", default=0.0, low=0.0, doc="friction coefficient mu"),
    Key("slip_velocity", default=1e-3, low=0.0, strict=True, unit="m/s",
        doc="below this sliding speed friction grows smoothly from 0 to mu times the normal force; "
            "small values make friction stiff"),
)


class PenaltyCollider(Effect):
    """Shared force, energy and Jacobian code; subclasses give the geometry.

    Subclasses implement ``_contact(x) -> (depth, normal, dnormal)`` where ``depth``
    has shape (n,) (positive inside), ``normal`` (n, dim) and ``dnormal`` the
    derivative of the normal with respect to x, (n, dim, dim), or None if constant.
    """

    section = "colliders"
    many = True
    order = 40
    kernel = staticmethod(penalty_kernel)
    may_touch = True

    def __init__(self, stiffness: float, friction: float = 0.0, slip_velocity: float = 1e-3):
        self.stiffness = float(stiffness)
        self.friction = float(friction)
        self.slip_velocity = float(slip_velocity)
        self.velocity_dependent = self.friction > 0.0
        self.dissipative = self.friction > 0.0
        self.conservative = True

    def _contact(self, x: np.ndarray):
        raise NotImplementedError

    def _geometry(self) -> tuple[int, np.ndarray, float]:
        """``(sphere, point, level)`` of :func:`penalty_kernel`."""
        raise NotImplementedError

    def kernel_params(self) -> tuple:
        """Return ``(sphere, point, level, stiffness, friction, slip_velocity)`` of :func:`penalty_kernel`."""
        return (*self._geometry(), self.stiffness, self.friction, self.slip_velocity)

    #: numpy cost of one particle in items of ``mslab.fast``'s cost model (a spring: 1), without
    #: and with friction; measured on this machine for 20 to 90,000 particles in 3D
    numpy_items_per_particle: tuple[float, float] = (1.0, 2.0)

    def kernel_items(self, n_particles: int) -> int:
        """Return the cost of one numpy evaluation in the cost model's items (``backend="auto"``).

        Every particle is tested for contact; the numpy code costs a fixed ~30 us (about
        500 items) plus :attr:`numpy_items_per_particle` per particle.
        """
        per = self.numpy_items_per_particle[1 if self.friction > 0.0 else 0]
        return int(500 + per * n_particles)

    def contact_jacobian(self, x: np.ndarray) -> sp.csr_matrix:
        """``df/dx = -k n n^T`` on every particle, as if all touched (capability: ``may_touch``).

        ``n`` is the collider's normal at the particle (for a particle at a sphere's centre,
        where it is undefined, the diagonal ``(1, ..., 1)/sqrt(dim)``); the curvature term
        is left out (it vanishes at zero depth).
        """
        _, normal, _ = self._contact(x)
        touching = np.linalg.norm(normal, axis=1, keepdims=True) > 0
        normal = np.where(touching, normal, 1.0 / np.sqrt(x.shape[1]))
        blocks = -self.stiffness * normal[:, :, None] * normal[:, None, :]
        return block_diagonal(blocks, np.arange(x.shape[0]), x.shape[0])

    def _active(self, x: np.ndarray):
        depth, normal, dnormal = self._contact(x)
        idx = np.flatnonzero(depth > 0.0)
        dn = None if dnormal is None else dnormal[idx]
        return idx, depth[idx], normal[idx], dn

    def _tangent(self, v: np.ndarray, n: np.ndarray):
        vt = v - np.einsum("ij,ij->i", n, v)[:, None] * n
        s = np.sqrt(np.einsum("ij,ij->i", vt, vt) + self.slip_velocity**2)
        return vt, s

    def force_and_power(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Return the penalty and friction forces and the power friction dissipates, from one pass."""
        f = np.zeros_like(x)
        idx, p, n, _ = self._active(x)
        if idx.size == 0:
            return f, 0.0
        fn = self.stiffness * p
        fi = fn[:, None] * n
        power = 0.0
        if self.friction > 0.0:
            vi = v[idx]
            vt, s = self._tangent(vi, n)
            ft = -(self.friction * fn / s)[:, None] * vt
            fi += ft
            power = float(-np.sum(ft * vi))
        f[idx] = fi
        return f, power

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return the penalty and friction forces, shape (n_particles, dim)."""
        return self.force_and_power(x, v)[0]

    def power(self, x: np.ndarray, v: np.ndarray) -> float:
        """Return the power friction dissipates, ``-f_t . v >= 0``."""
        return self.force_and_power(x, v)[1]

    def energy(self, x: np.ndarray) -> float:
        """Return the penalty energy ``sum k p^2 / 2`` over penetrating particles."""
        depth = self._contact(x)[0]
        p = depth[depth > 0.0]
        return float(0.5 * self.stiffness * np.sum(p * p))

    def jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix | None]:
        """Return ``(df/dx, df/dv)`` of the penalty and friction forces (df/dv None without friction)."""
        nparticles, dim = x.shape
        idx, p, n, dn = self._active(x)
        k = self.stiffness
        nn = n[:, :, None] * n[:, None, :]
        jx = -k * nn
        if dn is not None:
            jx = jx + k * p[:, None, None] * dn
        jv = None
        if self.friction > 0.0:
            vi = v[idx]
            vt, s = self._tangent(vi, n)
            t = vt / s[:, None]
            eye = np.eye(dim)[None]
            tmat = eye / s[:, None, None] - vt[:, :, None] * vt[:, None, :] / (s**3)[:, None, None]
            mu_k = self.friction * k
            # d f_t / d x: through the depth (-n^T) and, for curved colliders, the normal
            jx = jx + mu_k * t[:, :, None] * n[:, None, :]
            if dn is not None:
                nv = np.einsum("ij,ij->i", n, vi)
                v_dn = np.einsum("kb,kba->ka", vi, dn)
                dvt_dx = -(nv[:, None, None] * dn + n[:, :, None] * v_dn[:, None, :])
                jx = jx - mu_k * p[:, None, None] * np.einsum("kab,kbc->kac", tmat, dvt_dx)
            proj = eye - nn
            jv_blocks = -mu_k * p[:, None, None] * np.einsum("kab,kbc->kac", tmat, proj)
            jv = block_diagonal(jv_blocks, idx, nparticles)
        return block_diagonal(jx, idx, nparticles), jv


@register
class Plane(PenaltyCollider):
    """Half-space ``n . x >= offset``; particles below are pushed back up.

    Parameters
    ----------
    normal : array_like, shape (dim,)
        Outward normal (normalised here).
    offset : float
        The plane is ``n . x = offset``.
    stiffness, friction, slip_velocity : float
        Penalty stiffness k, friction coefficient mu, regularisation speed eps.
    """

    name = "plane"
    kind = "plane"
    keys = (
        Key("normal", "vector", doc="the side particles stay on (need not be unit length)"),
        Key("offset", doc="the plane is normal . x = offset (with the normal normalised)", unit="m"),
    ) + PENALTY_KEYS
    builder_methods = ("add_plane",)
    summary = "penalty half-space with regularised Coulomb friction"

    def __init__(self, normal: npt.ArrayLike, offset: float, stiffness: float, friction: float = 0.0,
                 slip_velocity: float = 1e-3):
        super().__init__(stiffness, friction, slip_velocity)
        normal = np.asarray(normal, dtype=float)
        self.normal = normal / np.linalg.norm(normal)
        self.offset = float(offset)

    def _contact(self, x: np.ndarray):
        depth = self.offset - x @ self.normal
        normal = np.broadcast_to(self.normal, x.shape)
        return depth, normal, None

    def _geometry(self) -> tuple[int, np.ndarray, float]:
        return 0, self.normal, self.offset

    def outline(self) -> Halfspace:
        """Return the half-space below the plane (capability: the plots draw it)."""
        return Halfspace(self.normal, self.offset)

    @staticmethod
    def add_plane(builder: Builder, normal: npt.ArrayLike, offset: float, stiffness: float,
                  friction: float = 0.0, slip_velocity: float = 1e-3) -> None:
        """Add a penalty half-space ``normal . x >= offset`` (``slip_velocity``: friction regularisation)."""
        builder.add_effect(Plane, normal=normal, offset=offset, stiffness=stiffness, friction=friction,
                           slip_velocity=slip_velocity)

    @classmethod
    def add(cls, builder: Builder, values: dict, prefix: str = "") -> None:
        """Record the plane after checking that its normal is not zero."""
        if not np.any(values["normal"]):
            raise SceneError(f"{prefix}normal", "must not be the zero vector")
        super().add(builder, values, prefix)

    @classmethod
    def create(cls, values: dict, ctx: BuildContext) -> Plane:
        """Return the plane of the checked values."""
        return cls(values["normal"], values["offset"], values["stiffness"], values["friction"],
                   values["slip_velocity"])

    @classmethod
    def example(cls, dim: int) -> dict:
        """Return a tilted plane with friction for the registry-wide tests."""
        normal = [0.0] * dim
        normal[-1] = 1.0
        normal[0] = 0.3
        return {"normal": normal, "offset": 0.1, "stiffness": 500.0, "friction": 0.4, "slip_velocity": 0.3}

    def __repr__(self):
        return f"Plane(normal={self.normal.tolist()}, offset={self.offset}, stiffness={self.stiffness})"


@register
class Sphere(PenaltyCollider):
    """Solid sphere (a disc in 2D): particles inside are pushed out radially.

    Parameters
    ----------
    center : array_like, shape (dim,)
    radius, stiffness, friction, slip_velocity : float
    """

    name = "sphere"
    kind = "sphere"
    keys = (
        Key("center", "vector", unit="m", doc="centre of the ball (a disc in 2D)"),
        Key("radius", low=0.0, strict=True, unit="m", doc="radius of the ball"),
    ) + PENALTY_KEYS
    builder_methods = ("add_sphere",)
    summary = "penalty ball (disc in 2D) with regularised Coulomb friction"
    numpy_items_per_particle = (3.0, 5.0)

    def __init__(self, center: npt.ArrayLike, radius: float, stiffness: float, friction: float = 0.0,
                 slip_velocity: float = 1e-3):
        super().__init__(stiffness, friction, slip_velocity)
        self.center = np.asarray(center, dtype=float)
        self.radius = float(radius)

    def _contact(self, x: np.ndarray):
        y = x - self.center
        r = np.sqrt(np.einsum("ij,ij->i", y, y))
        safe = np.where(r > 0.0, r, 1.0)
        normal = np.where((r > 0.0)[:, None], y / safe[:, None], 0.0)
        dim = x.shape[1]
        proj = np.eye(dim)[None] - normal[:, :, None] * normal[:, None, :]
        dnormal = proj / safe[:, None, None]
        return self.radius - r, normal, dnormal

    def _geometry(self) -> tuple[int, np.ndarray, float]:
        return 1, self.center, self.radius

    def outline(self) -> Ball:
        """Return the ball (capability: the plots draw it)."""
        return Ball(self.center, self.radius)

    @staticmethod
    def add_sphere(builder: Builder, center: npt.ArrayLike, radius: float, stiffness: float,
                   friction: float = 0.0, slip_velocity: float = 1e-3) -> None:
        """Add a penalty sphere (disc in 2D); ``slip_velocity``: friction regularisation."""
        builder.add_effect(Sphere, center=center, radius=radius, stiffness=stiffness, friction=friction,
                           slip_velocity=slip_velocity)

    @classmethod
    def create(cls, values: dict, ctx: BuildContext) -> Sphere:
        """Return the sphere of the checked values."""
        return cls(values["center"], values["radius"], values["stiffness"], values["friction"],
                   values["slip_velocity"])

    @classmethod
    def example(cls, dim: int) -> dict:
        """Return a ball with friction for the registry-wide tests."""
        return {"center": [0.1] * dim, "radius": 1.0, "stiffness": 300.0, "friction": 0.5,
                "slip_velocity": 0.2}

    def __repr__(self):
        return f"Sphere(center={self.center.tolist()}, radius={self.radius}, stiffness={self.stiffness})"
