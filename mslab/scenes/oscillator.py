"""The harmonic oscillator: the course's model problem, with its closed-form solution."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.scene import Scene
from mslab.scenes.builder import SceneBuilder

if TYPE_CHECKING:
    import numpy.typing as npt


def oscillator_solution(t: npt.ArrayLike, u0: float, w0: float, beta: float,
                        v0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Return the closed form of ``u'' + 2 beta u' + w0^2 u = 0``: ``(u(t), u'(t))``.

    Under-, critically and over-damped cases through one complex formula
    ``u = e^{-beta t} (u0 cos(wd t) + (v0 + beta u0) sin(wd t)/wd)``, ``wd = sqrt(w0^2 - beta^2)``.
    """
    t = np.asarray(t, dtype=float)
    wd = np.sqrt(complex(w0 * w0 - beta * beta))
    decay = np.exp(-beta * t)
    B = v0 + beta * u0
    if abs(wd) < 1e-12 * max(w0, 1.0):
        sin_over = t.astype(complex)       # sin(wd t)/wd -> t
        cos_wd = np.ones_like(t, dtype=complex)
        dsin_over = np.ones_like(t, dtype=complex)   # d/dt [sin(wd t)/wd] = cos(wd t)
        dcos = np.zeros_like(t, dtype=complex)
    else:
        sin_over = np.sin(wd * t) / wd
        cos_wd = np.cos(wd * t)
        dsin_over = cos_wd
        dcos = -wd * np.sin(wd * t)
    u = decay * (u0 * cos_wd + B * sin_over)
    du = -beta * u + decay * (u0 * dcos + B * dsin_over)
    return u.real, du.real


def oscillator(stiffness: float = 1.0, mass: float = 1.0, gamma: float = 0.0,
               displacement: float = 0.5, velocity: float = 0.0, rest_length: float = 1.0,
               dim: int = 1, t_end: float = 2.0 * np.pi, dt: float = 0.01) -> Scene:
    """One mass on a spring to a pinned anchor, optionally with viscous drag.

    ``m u'' = -k u - gamma u'`` for the stretch ``u``: the course's model problem, with a
    closed-form solution attached as ``scene.exact``. Keep ``|displacement|`` below
    ``rest_length`` (and the amplitude with it): a 1D spring squeezed through zero length
    flips direction and the dynamics is no longer linear.
    """
    b = SceneBuilder(dim)
    e = np.zeros(dim)
    e[0] = 1.0
    anchor = b.add_particle(np.zeros(dim), mass=mass, pinned=True)
    p = b.add_particle((rest_length + displacement) * e, mass=mass, velocity=velocity * e)
    b.add_spring(anchor, p, stiffness, rest_length=rest_length)
    if gamma > 0:
        b.add_damping(gamma)
    b.set_run(method="rk4", dt=dt, t_end=t_end)
    w0 = float(np.sqrt(stiffness / mass))
    beta = gamma / (2.0 * mass)

    def exact(t: npt.ArrayLike):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        u, du = oscillator_solution(t, displacement, w0, beta, velocity)
        x = np.zeros((t.size, 2, dim))
        v = np.zeros((t.size, 2, dim))
        x[:, 1, 0] = rest_length + u
        v[:, 1, 0] = du
        return x, v

    kind = "damped " if gamma > 0 else ""
    return b.build("oscillator", f"{kind}harmonic oscillator, w0 = {w0:g}", exact=exact)
