"""Programmatic scenes: ``SceneBuilder`` collects particles and effects, ``build()`` freezes them.

Only the effects added to the builder exist in the built :class:`~mslab.system.System`:
a scene without colliders never creates (or evaluates) collider code. The effect methods
(``add_spring``, ``add_gravity``, ``add_plane`` ...) are defined once, by the effect classes,
and are attributes of ``SceneBuilder`` (listed in its class body; those of an effect module
added to ``mslab/effects/`` are attached when the registry registers it). The TOML loader
adds effects through the same methods. Every call costs O(1) amortised, whatever the
scene's size (``tests/test_builder_cost.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from mslab.checks import flag, real, shown, whole
from mslab.effects import Anchors, Damping, Gravity, Plane, Sphere, Springs, Wind, registry
from mslab.effects.base import BuildContext, Effect
from mslab.effects.schema import check_values, describe
from mslab.errors import SceneError
from mslab.scene import Scene, Settings, spring_effect
from mslab.state import State
from mslab.system import System

if TYPE_CHECKING:
    import numpy.typing as npt


class _Rows:
    """An array grown by appending rows: doubling capacity, so an append costs O(1) amortised."""

    def __init__(self, shape: tuple[int, ...], dtype: type):
        self._data = np.zeros((16, *shape), dtype=dtype)
        self.n = 0

    def _reserve(self, m: int) -> None:
        if self.n + m > self._data.shape[0]:
            grown = np.zeros((max(2 * self._data.shape[0], self.n + m), *self._data.shape[1:]),
                             dtype=self._data.dtype)
            grown[: self.n] = self._data[: self.n]
            self._data = grown

    def append(self, row: Any) -> None:
        """Add one row."""
        self._reserve(1)
        self._data[self.n] = row
        self.n += 1

    def extend(self, rows: np.ndarray) -> None:
        """Add ``len(rows)`` rows."""
        self._reserve(rows.shape[0])
        self._data[self.n: self.n + rows.shape[0]] = rows
        self.n += rows.shape[0]

    def __setitem__(self, index: int, value: Any) -> None:
        self._data[index] = value

    def view(self) -> np.ndarray:
        """Return the rows so far, without a copy (read-only)."""
        out = self._data[: self.n]
        out.flags.writeable = False
        return out


def _numbers(value: npt.ArrayLike, key: str) -> np.ndarray:
    """Return ``value`` as a float array: real numbers only (no text, bools or complex numbers)."""
    raw = np.asarray(value)
    if raw.dtype.kind == "O":                    # Python ints beyond any float, or mixed objects
        if not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                   for v in raw.reshape(-1)):
            raise TypeError(f"{key} must be real numbers, got {shown(value)}")
        try:
            return raw.astype(float)
        except OverflowError:
            raise SceneError(key, "must be finite numbers") from None
    if raw.dtype.kind not in "iuf":
        raise TypeError(f"{key} must be real numbers, got {raw.dtype.name} values {shown(value)}")
    return raw.astype(float)


class SceneBuilder:
    """Collects particles, springs and effects; ``build()`` returns a :class:`Scene`.

    Effect methods (``add_spring``, ``add_springs``, ``add_gravity``, ``add_damping``,
    ``add_plane``, ``add_sphere``, ``add_anchors``, ``add_wind`` and those of any effect
    module added to ``mslab/effects/``) are defined by the effect classes.

    Parameters
    ----------
    dim : int
        1, 2 or 3.
    """

    def __init__(self, dim: int = 2):
        if whole("dim", dim) not in (1, 2, 3):
            raise SceneError("dim", f"must be 1, 2 or 3, got {dim!r}")
        self.dim = dim
        self._x = _Rows((dim,), float)
        self._v = _Rows((dim,), float)
        self._m = _Rows((), float)
        self._pinned = _Rows((), bool)
        self._entries: dict[type[Effect], list] = {}
        self.settings = Settings()

    # -- particles ----------------------------------------------------------------
    def _vector(self, value: npt.ArrayLike, key: str) -> np.ndarray:
        arr = _numbers(value, key).reshape(-1)
        if arr.shape != (self.dim,):
            raise SceneError(key, f"expected {self.dim} coordinates, got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise SceneError(key, "must be finite numbers")
        return arr

    def _checked(self, position: npt.ArrayLike, mass: float,
                 velocity: npt.ArrayLike | None) -> tuple[np.ndarray, np.ndarray | float]:
        """Return the checked position and velocity (0.0 for none) of a particle, or raise SceneError."""
        if not np.isfinite(real("mass", mass, allow_inf=True)) or mass <= 0:
            raise SceneError("mass", f"must be > 0, got {mass!r}")
        x = self._vector(position, "position")
        return x, 0.0 if velocity is None else self._vector(velocity, "velocity")

    def add_particle(self, position: npt.ArrayLike, mass: float = 1.0, pinned: bool = False,
                     velocity: npt.ArrayLike | None = None) -> int:
        """Add one mass point; return its index."""
        x, vel = self._checked(position, mass, velocity)
        flag("pinned", pinned)
        self._x.append(x)
        self._v.append(0.0 if pinned else vel)
        self._m.append(float(mass))
        self._pinned.append(flag("pinned", pinned))
        return self._x.n - 1

    def add_particles(self, positions: npt.ArrayLike, mass: npt.ArrayLike = 1.0,
                      velocity: npt.ArrayLike | None = None) -> np.ndarray:
        """Add many particles at once; return their indices (ndarray)."""
        pos = _numbers(positions, "positions").reshape(-1, self.dim)
        masses = np.broadcast_to(_numbers(mass, "mass"), (pos.shape[0],))
        vel = np.zeros_like(pos) if velocity is None else np.broadcast_to(_numbers(velocity, "velocity"),
                                                                          pos.shape)
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel)) and np.all(np.isfinite(masses))
                and np.all(masses > 0)):  # one by one, so that the first mistake is named
            for p, m, w in zip(pos, masses, vel, strict=True):
                self._checked(p, m, w)
        start = self._x.n
        self._x.extend(pos)
        self._v.extend(vel)
        self._m.extend(masses)
        self._pinned.extend(np.zeros(pos.shape[0], dtype=bool))
        return np.arange(start, self._x.n, dtype=np.int64)

    def pin(self, index: int) -> None:
        """Pin a particle in place (inv_mass = 0, velocity 0)."""
        self._check_index(index, "pinned")
        self._pinned[index] = True
        self._v[index] = 0.0

    def _check_index(self, i: int, key: str) -> int:
        n = self._x.n
        if not (isinstance(i, int | np.integer)) or not 0 <= int(i) < n:
            raise SceneError(key, f"particle index {i!r} out of range 0..{n - 1}")
        return int(i)

    # -- effects: each method is defined once, by its effect class (here so that tools see it) -----
    add_springs = Springs.add_springs
    add_spring = Springs.add_spring
    add_gravity = Gravity.add_gravity
    add_damping = Damping.add_damping
    add_anchors = Anchors.add_anchors
    add_plane = Plane.add_plane
    add_sphere = Sphere.add_sphere
    add_wind = Wind.add_wind

    def entries(self, effect: type[Effect]) -> list:
        """Return the entries recorded for an effect class (the list its ``build`` receives); mutable."""
        return self._entries.setdefault(effect, [])

    def add_effect(self, effect: type[Effect], **raw) -> None:
        """Check keyword values against the effect's schema and record them (builder methods use this)."""
        prefix = f"{effect.name}."
        effect.add(self, self.check_effect(effect, raw, prefix), prefix)

    def check_effect(self, effect: type[Effect], raw: dict, prefix: str, n: int | None = None) -> dict:
        """Return the values of ``raw`` checked against ``effect.keys`` (errors named ``prefix + key``).

        ``n``: how many particles indices may refer to (default: all added so far).
        """
        return check_values(effect.keys, raw, prefix, self.dim, self.n_particles if n is None else n)

    @staticmethod
    def check_table(value: Any, key: str) -> dict:
        """Return ``value`` if it is a table (a dict), else raise SceneError naming ``key``."""
        if not isinstance(value, dict):
            raise SceneError(key, f"must be a table ([{key}]), got {describe(value)}")
        return value

    @staticmethod
    def error(key: str, reason: str) -> SceneError:
        """Return the error to raise for a mistake at ``key``."""
        return SceneError(key, reason)

    def set_run(self, **settings) -> None:
        """Default run settings: method, dt, t_end, save_every."""
        self.settings = replace(self.settings, **settings)

    # -- build --------------------------------------------------------------------
    @property
    def n_particles(self) -> int:
        """Number of particles added so far."""
        return self._x.n

    def positions(self) -> np.ndarray:
        """Positions of the particles added so far, shape (n_particles, dim): a read-only view, O(1)."""
        return self._x.view()

    def build(self, name: str = "scene", description: str = "", exact: Callable | None = None) -> Scene:
        """Freeze everything into arrays; only the effects added here are created.

        Effects are ordered by their class's ``order`` (springs, gravity, damping, anchors,
        colliders), then by when they were first added.
        """
        if not self._x.n:
            raise SceneError("particles", "a scene needs at least one particle")
        x, v = self._x.view().copy(), self._v.view().copy()
        mass, pinned = self._m.view().copy(), self._pinned.view().copy()
        ctx = BuildContext(x, v, mass, pinned, self.dim)
        effects: list[Effect] = []
        for cls, entries in sorted(self._entries.items(), key=lambda item: item[0].order):
            if entries:
                effects.extend(cls.build(entries, ctx))
        system = System(mass, pinned, effects, self.dim)
        springs = spring_effect(effects)
        kind = springs.hooke_springs().kind if springs is not None else np.array([], dtype=str)
        return Scene(system, State(x, v), self.settings, name, description, kind, exact)


def _provide_methods(effect: type[Effect]) -> None:
    """Give ``SceneBuilder`` the builder methods of an effect registered later (a course's own effect).

    The built-in effects' methods are listed in the class body; this adds those of an
    effect module found in ``mslab.effects`` after this module was imported.
    """
    for name in effect.builder_methods:
        function = getattr(effect, name)
        current = SceneBuilder.__dict__.get(name)
        if current is function:
            continue
        if current is not None and name in _OWN:
            raise ValueError(f"{effect.__name__}: builder method '{name}' would replace SceneBuilder.{name}")
        setattr(SceneBuilder, name, function)


_OWN = set(vars(SceneBuilder)) - set(registry.builder_method_names())
registry.on_register(_provide_methods)
