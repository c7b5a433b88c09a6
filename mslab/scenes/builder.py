"""Programmatic scenes: ``SceneBuilder`` collects particles and effects, ``build()`` freezes them.

Only the effects added to the builder exist in the built :class:`~mslab.system.System`:
a scene without colliders never creates (or evaluates) collider code.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from mslab.effects import Damping, Gravity, Plane, Sphere, Springs
from mslab.errors import SceneError
from mslab.state import State
from mslab.system import System


@dataclass(frozen=True)
class Settings:
    """Run settings a scene suggests: method, step, end time and output thinning."""

    method: str = "rk4"
    dt: float = 1e-3
    t_end: float = 1.0
    save_every: int = 1


@dataclass
class Scene:
    """A built scene.

    Attributes
    ----------
    system : System
    state0 : State
        Initial positions and velocities.
    settings : Settings
    name, description : str
    spring_kind : ndarray of str, shape (n_springs,)
        ``structural``, ``shear``, ``bend`` or any label the builder was given.
    exact : callable or None
        ``exact(t) -> (x, v)`` for scenes with a closed-form solution (oscillators),
        t an array of times; x and v of shape (len(t), n_particles, dim).
    """

    system: System
    state0: State
    settings: Settings = field(default_factory=Settings)
    name: str = "scene"
    description: str = ""
    spring_kind: np.ndarray = field(default_factory=lambda: np.array([], dtype=str))
    exact: Callable | None = None

    @property
    def dim(self) -> int:
        return self.system.dim

    @property
    def n_particles(self) -> int:
        return self.system.n_particles

    @property
    def effects(self) -> list[str]:
        """Names of the effects the system evaluates."""
        return self.system.effect_names()

    def springs(self) -> Springs | None:
        """The springs effect, if the scene has springs."""
        for e in self.system.effects:
            if isinstance(e, Springs):
                return e
        return None

    def summary(self) -> dict:
        """Size, effects and default run settings, as plain data (for tables and JSON)."""
        s = self.settings
        return {"scene": self.name, "description": self.description, "dim": self.dim,
                "n_particles": self.n_particles, "n_springs": len(self.spring_kind),
                "effects": self.effects, "method": s.method, "dt": s.dt, "t_end": s.t_end,
                "save_every": s.save_every}

    def with_settings(self, **changes) -> Scene:
        """A copy of the scene with some run settings replaced."""
        return replace(self, settings=replace(self.settings, **changes))


class SceneBuilder:
    """Collects particles, springs and effects; ``build()`` returns a :class:`Scene`.

    Parameters
    ----------
    dim : int
        1, 2 or 3.
    """

    def __init__(self, dim: int = 2):
        if dim not in (1, 2, 3):
            raise SceneError("dim", f"must be 1, 2 or 3, got {dim!r}")
        self.dim = dim
        self._x: list[np.ndarray] = []
        self._v: list[np.ndarray] = []
        self._m: list[float] = []
        self._pinned: list[bool] = []
        self._springs: list[tuple[int, int]] = []
        self._k: list[float] = []
        self._rest: list[float | None] = []
        self._c: list[float] = []
        self._kind: list[str] = []
        self._gravity = None
        self._gamma = None
        self._colliders: list[tuple] = []
        self.settings = Settings()

    # -- particles ----------------------------------------------------------------
    def _vector(self, value, key: str) -> np.ndarray:
        arr = np.asarray(value, dtype=float).reshape(-1)
        if arr.shape != (self.dim,):
            raise SceneError(key, f"expected {self.dim} coordinates, got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise SceneError(key, "must be finite numbers")
        return arr

    def add_particle(self, position, mass: float = 1.0, pinned: bool = False, velocity=None) -> int:
        """Add one mass point; returns its index."""
        if not np.isfinite(mass) or mass <= 0:
            raise SceneError("mass", f"must be > 0, got {mass!r}")
        self._x.append(self._vector(position, "position"))
        vel = np.zeros(self.dim) if velocity is None else self._vector(velocity, "velocity")
        self._v.append(np.zeros(self.dim) if pinned else vel)
        self._m.append(float(mass))
        self._pinned.append(bool(pinned))
        return len(self._x) - 1

    def add_particles(self, positions, mass=1.0, velocity=None) -> np.ndarray:
        """Add many particles at once; returns their indices (ndarray)."""
        pos = np.asarray(positions, dtype=float).reshape(-1, self.dim)
        masses = np.broadcast_to(np.asarray(mass, dtype=float), (pos.shape[0],))
        vel = np.zeros_like(pos) if velocity is None else np.broadcast_to(
            np.asarray(velocity, dtype=float), pos.shape)
        return np.array([self.add_particle(p, m, False, w) for p, m, w in zip(pos, masses, vel, strict=True)],
                        dtype=np.int64)

    def pin(self, index: int) -> None:
        """Pin a particle in place (inv_mass = 0, velocity 0)."""
        self._check_index(index, "pinned")
        self._pinned[index] = True
        self._v[index] = np.zeros(self.dim)

    def _check_index(self, i, key: str) -> int:
        n = len(self._x)
        if not (isinstance(i, int | np.integer)) or not 0 <= int(i) < n:
            raise SceneError(key, f"particle index {i!r} out of range 0..{n - 1}")
        return int(i)

    # -- springs ------------------------------------------------------------------
    def add_spring(self, i: int, j: int, stiffness: float, rest_length: float | None = None,
                   damping: float = 0.0, kind: str = "structural") -> int:
        """Spring between particles i and j; ``rest_length=None`` takes the current length."""
        i = self._check_index(i, "springs")
        j = self._check_index(j, "springs")
        if i == j:
            raise SceneError("springs", f"a spring needs two different particles, got ({i}, {j})")
        for value, key in ((stiffness, "stiffness"), (damping, "damping")):
            if not np.isfinite(value) or value < 0:
                raise SceneError(key, f"must be a finite number >= 0, got {value!r}")
        if rest_length is not None and (not np.isfinite(rest_length) or rest_length < 0):
            raise SceneError("rest_length", f"must be a finite number >= 0, got {rest_length!r}")
        if rest_length is None and np.linalg.norm(self._x[i] - self._x[j]) == 0.0:
            raise SceneError("rest_length", f"spring ({i}, {j}) has zero length in the initial positions; "
                             "give its rest length explicitly")
        self._springs.append((i, j))
        self._k.append(float(stiffness))
        self._rest.append(rest_length)
        self._c.append(float(damping))
        self._kind.append(kind)
        return len(self._springs) - 1

    def add_springs(self, pairs, stiffness: float, rest_length=None, damping: float = 0.0,
                    kind: str = "structural") -> None:
        """Add springs for every ``(i, j)`` in ``pairs`` with the same parameters."""
        for i, j in np.asarray(pairs, dtype=np.int64).reshape(-1, 2):
            self.add_spring(int(i), int(j), stiffness, rest_length, damping, kind)

    # -- other effects ------------------------------------------------------------
    def add_gravity(self, g) -> None:
        """Uniform gravity, e.g. ``[0, -9.81]``."""
        self._gravity = self._vector(g, "gravity.g")

    def add_damping(self, gamma: float) -> None:
        """Viscous drag ``f = -gamma v`` on every particle."""
        if not np.isfinite(gamma) or gamma < 0:
            raise SceneError("damping.gamma", f"must be a finite number >= 0, got {gamma!r}")
        self._gamma = float(gamma)

    def _collider_params(self, stiffness, friction, slip_velocity=1e-3):
        if not np.isfinite(stiffness) or stiffness <= 0:
            raise SceneError("stiffness", f"must be > 0, got {stiffness!r}")
        if not np.isfinite(friction) or friction < 0:
            raise SceneError("friction", f"must be >= 0, got {friction!r}")
        if not np.isfinite(slip_velocity) or slip_velocity <= 0:
            raise SceneError("slip_velocity", f"must be > 0, got {slip_velocity!r}")

    def add_plane(self, normal, offset: float, stiffness: float, friction: float = 0.0,
                  slip_velocity: float = 1e-3) -> None:
        """Penalty half-space ``normal . x >= offset`` (``slip_velocity``: friction regularisation)."""
        n = self._vector(normal, "plane.normal")
        if np.linalg.norm(n) == 0:
            raise SceneError("plane.normal", "must not be the zero vector")
        self._collider_params(stiffness, friction, slip_velocity)
        self._colliders.append(("plane", n, float(offset), float(stiffness), float(friction),
                                float(slip_velocity)))

    def add_sphere(self, center, radius: float, stiffness: float, friction: float = 0.0,
                   slip_velocity: float = 1e-3) -> None:
        """Penalty sphere (disc in 2D); ``slip_velocity``: friction regularisation."""
        c = self._vector(center, "sphere.center")
        if not np.isfinite(radius) or radius <= 0:
            raise SceneError("sphere.radius", f"must be > 0, got {radius!r}")
        self._collider_params(stiffness, friction, slip_velocity)
        self._colliders.append(("sphere", c, float(radius), float(stiffness), float(friction),
                                float(slip_velocity)))

    def set_run(self, **settings) -> None:
        """Default run settings: method, dt, t_end, save_every."""
        self.settings = replace(self.settings, **settings)

    # -- build --------------------------------------------------------------------
    @property
    def n_particles(self) -> int:
        return len(self._x)

    def positions(self) -> np.ndarray:
        return np.array(self._x, dtype=float).reshape(-1, self.dim)

    def build(self, name: str = "scene", description: str = "", exact: Callable | None = None) -> Scene:
        """Freeze everything into arrays; only the effects added here are created."""
        if not self._x:
            raise SceneError("particles", "a scene needs at least one particle")
        x = self.positions()
        v = np.array(self._v, dtype=float).reshape(-1, self.dim)
        mass = np.array(self._m)
        n = len(mass)
        effects = []
        if self._springs:
            pairs = np.array(self._springs, dtype=np.int64)
            lengths = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
            rest = np.array([lengths[q] if r is None else r for q, r in enumerate(self._rest)])
            effects.append(Springs(pairs, np.array(self._k), rest, np.array(self._c), n))
        if self._gravity is not None:
            effects.append(Gravity(self._gravity, mass))
        if self._gamma is not None and self._gamma > 0:
            effects.append(Damping(self._gamma, n, self.dim))
        for kind, a, b, k, mu, eps in self._colliders:
            effects.append(Plane(a, b, k, mu, eps) if kind == "plane" else Sphere(a, b, k, mu, eps))
        system = System(mass, np.array(self._pinned), effects, self.dim)
        return Scene(system, State(x, v), self.settings, name, description,
                     np.array(self._kind, dtype=str), exact)
