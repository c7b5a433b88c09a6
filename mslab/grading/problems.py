"""Small test problems handed to student functions: ``accel(x, v)`` and its Jacobians.

A :class:`Problem` is particles with masses (some pinned), Hooke springs, uniform
gravity and viscous drag; it is callable, ``problem(x, v) -> a`` of shape
(n_particles, dim), and gives the dense Jacobians of the acceleration for Newton's method.
It is written with numpy only so the grading sandbox can rebuild it from its recipe
(name and parameters) without importing mslab; ``problem.system()`` builds the same model
as an :class:`mslab.System` for reference solutions (a test checks both agree).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import numpy.typing as npt

    from mslab.system import System


class Problem:
    """A mass-spring model as a callable acceleration.

    Attributes
    ----------
    x0, v0 : ndarray, shape (n_particles, dim)
        Initial state.
    mass : ndarray, shape (n_particles,)
    pinned : ndarray of bool, shape (n_particles,)
    springs : ndarray of int, shape (n_springs, 2)
    stiffness, rest_length : ndarray, shape (n_springs,)
    gravity : ndarray, shape (dim,)
    gamma : float
        Viscous drag ``f = -gamma v``.
    n_calls : int
        How often the acceleration was evaluated (locally).
    """

    def __init__(self, name: str, **params):
        builders = {"oscillator": _oscillator, "chain": _chain}
        if name not in builders:
            raise ValueError(f"unknown problem {name!r}")
        self.name = name
        self.params = {k: (float(v) if isinstance(v, float) else v) for k, v in params.items()}
        builders[name](self, **params)
        self.inv_mass = np.where(self.pinned, 0.0, 1.0 / self.mass)
        self.n_calls = 0

    def __wire__(self) -> dict:
        return {"name": self.name, "params": dict(self.params)}

    @property
    def dim(self) -> int:
        """Number of space dimensions."""
        return self.x0.shape[1]

    def __call__(self, x: npt.ArrayLike, v: npt.ArrayLike | None = None) -> np.ndarray:
        """Return the acceleration ``a(x, v)``, shape (n_particles, dim); ``v=None`` means at rest."""
        self.n_calls += 1
        x = np.asarray(x, dtype=float)
        v = np.zeros_like(x) if v is None else np.asarray(v, dtype=float)
        # Hooke's law written here again, not mslab.effects.springs.Springs.force: this file is
        # copied into the grading sandbox (isolation.SANDBOX_FILES), which imports numpy but not
        # mslab, and it is the independent reference the library's springs are tested against
        # (tests/test_grading.py, test_problems_agree_with_the_library).
        d = x[self.springs[:, 0]] - x[self.springs[:, 1]]
        length = np.linalg.norm(d, axis=1)
        fpair = (self.stiffness * (self.rest_length - length) / length)[:, None] * d
        f = np.zeros_like(x)
        np.add.at(f, self.springs[:, 0], fpair)
        np.add.at(f, self.springs[:, 1], -fpair)
        f += self.mass[:, None] * self.gravity[None, :] - self.gamma * v
        return self.inv_mass[:, None] * f

    acceleration = __call__

    def jacobians(self, x: npt.ArrayLike, v: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Return the dense ``(da/dx, da/dv)``, ordered (particle, axis).

        Each has shape (n_particles*dim, n_particles*dim).
        """
        x = np.asarray(x, dtype=float)
        n, dim = x.shape
        K = np.zeros((n * dim, n * dim))
        for (i, j), k, rest in zip(self.springs, self.stiffness, self.rest_length, strict=True):
            d = x[i] - x[j]
            length = np.linalg.norm(d)
            u = d / length
            block = -k * (np.outer(u, u) + (1.0 - rest / length) * (np.eye(dim) - np.outer(u, u)))
            si, sj = slice(i * dim, (i + 1) * dim), slice(j * dim, (j + 1) * dim)
            K[si, si] += block
            K[sj, sj] += block
            K[si, sj] -= block
            K[sj, si] -= block
        minv = np.repeat(self.inv_mass, dim)
        D = -self.gamma * np.diag(minv)
        return minv[:, None] * K, D

    def system(self) -> System:
        """Return the same model as an :class:`mslab.System` (for reference solutions)."""
        from mslab.scenes.builder import SceneBuilder

        b = SceneBuilder(self.dim)
        for xi, vi, m, p in zip(self.x0, self.v0, self.mass, self.pinned, strict=True):
            b.add_particle(xi, mass=float(m), velocity=vi, pinned=bool(p))
        for (i, j), k, rest in zip(self.springs, self.stiffness, self.rest_length, strict=True):
            b.add_spring(int(i), int(j), float(k), rest_length=float(rest))
        if np.any(self.gravity != 0.0):
            b.add_gravity(self.gravity)
        if self.gamma > 0.0:
            b.add_damping(self.gamma)
        return b.build(self.name).system

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"problem({self.name!r}, {args})"


def _oscillator(p: Problem, stiffness: float = 1.0, mass: float = 1.0, displacement: float = 0.5,
                rest_length: float = 1.0, gamma: float = 0.0, dim: int = 1):
    e = np.zeros(dim)
    e[0] = 1.0
    p.x0 = np.array([np.zeros(dim), (rest_length + displacement) * e])
    p.v0 = np.zeros((2, dim))
    p.mass = np.array([float(mass), float(mass)])
    p.pinned = np.array([True, False])
    p.springs = np.array([[0, 1]])
    p.stiffness = np.array([float(stiffness)])
    p.rest_length = np.array([float(rest_length)])
    p.gravity = np.zeros(dim)
    p.gamma = float(gamma)


def _chain(p: Problem, n: int = 5, dim: int = 2, length: float = 1.0, mass: float = 1.0,
           stiffness: float = 100.0, gravity: float = 9.81, gamma: float = 0.0, sag: float = 0.0):
    """``n`` particles on the x axis, the first pinned; ``sag`` bends it into a parabola."""
    s = np.linspace(0.0, 1.0, n)
    p.x0 = np.zeros((n, dim))
    p.x0[:, 0] = length * s
    if dim > 1:
        p.x0[:, 1] = -sag * s * s
    p.v0 = np.zeros((n, dim))
    p.mass = np.full(n, float(mass) / n)
    p.pinned = np.arange(n) == 0
    p.springs = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    p.stiffness = np.full(n - 1, float(stiffness))
    p.rest_length = np.full(n - 1, float(length) / (n - 1))
    p.gravity = np.zeros(dim)
    p.gravity[min(1, dim - 1)] = -float(gravity)
    p.gamma = float(gamma)


def problem(name: str, **params) -> Problem:
    """Return a test problem by name: ``"oscillator"`` or ``"chain"`` (see the module docstring)."""
    return Problem(name, **params)
