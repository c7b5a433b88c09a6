"""Penalty colliders: a plane and a sphere, with optional friction (seed section 2.7).

A particle that penetrates a collider by a depth ``p > 0`` feels a spring pushing it
back along the surface normal ``n``: ``f_n = k p n`` with potential ``U = k p^2 / 2``.
Friction is regularised Coulomb friction opposing the tangential velocity
``v_t = v - (n . v) n``::

    f_t = -mu |f_n| v_t / sqrt(|v_t|^2 + eps^2)

which tends to the Coulomb law ``-mu |f_n| v_t/|v_t|`` for ``|v_t| >> eps`` and stays
smooth (and differentiable for Newton) at rest. It dissipates ``P = -f_t . v >= 0``.
"""

from __future__ import annotations

import numpy as np

from mslab.effects.base import Effect, block_diagonal


class PenaltyCollider(Effect):
    """Shared force, energy and Jacobian code; subclasses give the geometry.

    Subclasses implement ``_contact(x) -> (depth, normal, dnormal)`` where ``depth``
    has shape (n,) (positive inside), ``normal`` (n, dim) and ``dnormal`` the
    derivative of the normal with respect to x, (n, dim, dim), or None if constant.
    """

    def __init__(self, stiffness: float, friction: float = 0.0, slip_velocity: float = 1e-3):
        self.stiffness = float(stiffness)
        self.friction = float(friction)
        self.slip_velocity = float(slip_velocity)
        self.velocity_dependent = self.friction > 0.0
        self.dissipative = self.friction > 0.0
        self.conservative = True

    def _contact(self, x):
        raise NotImplementedError

    def _active(self, x):
        depth, normal, dnormal = self._contact(x)
        idx = np.flatnonzero(depth > 0.0)
        dn = None if dnormal is None else dnormal[idx]
        return idx, depth[idx], normal[idx], dn

    def _tangent(self, v, n):
        vt = v - np.einsum("ij,ij->i", n, v)[:, None] * n
        s = np.sqrt(np.einsum("ij,ij->i", vt, vt) + self.slip_velocity**2)
        return vt, s

    def force_and_power(self, x, v):
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

    def force(self, x, v):
        return self.force_and_power(x, v)[0]

    def power(self, x, v):
        return self.force_and_power(x, v)[1]

    def energy(self, x):
        depth = self._contact(x)[0]
        p = depth[depth > 0.0]
        return float(0.5 * self.stiffness * np.sum(p * p))

    def jacobians(self, x, v):
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

    def __init__(self, normal, offset: float, stiffness: float, friction: float = 0.0,
                 slip_velocity: float = 1e-3):
        super().__init__(stiffness, friction, slip_velocity)
        normal = np.asarray(normal, dtype=float)
        self.normal = normal / np.linalg.norm(normal)
        self.offset = float(offset)

    def _contact(self, x):
        depth = self.offset - x @ self.normal
        normal = np.broadcast_to(self.normal, x.shape)
        return depth, normal, None

    def __repr__(self):
        return f"Plane(normal={self.normal.tolist()}, offset={self.offset}, stiffness={self.stiffness})"


class Sphere(PenaltyCollider):
    """Solid sphere (a disc in 2D): particles inside are pushed out radially.

    Parameters
    ----------
    center : array_like, shape (dim,)
    radius, stiffness, friction, slip_velocity : float
    """

    name = "sphere"

    def __init__(self, center, radius: float, stiffness: float, friction: float = 0.0,
                 slip_velocity: float = 1e-3):
        super().__init__(stiffness, friction, slip_velocity)
        self.center = np.asarray(center, dtype=float)
        self.radius = float(radius)

    def _contact(self, x):
        y = x - self.center
        r = np.sqrt(np.einsum("ij,ij->i", y, y))
        safe = np.where(r > 0.0, r, 1.0)
        normal = np.where((r > 0.0)[:, None], y / safe[:, None], 0.0)
        dim = x.shape[1]
        proj = np.eye(dim)[None] - normal[:, :, None] * normal[:, None, :]
        dnormal = proj / safe[:, None, None]
        return self.radius - r, normal, dnormal

    def __repr__(self):
        return f"Sphere(center={self.center.tolist()}, radius={self.radius}, stiffness={self.stiffness})"
