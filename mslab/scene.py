"""What a scene is, as plain data: :class:`Scene` (a System, its initial State, run Settings).

How a scene is built (``SceneBuilder``, generators, TOML files) is in :mod:`mslab.scenes`,
which sits above the stepping code; this module sits below it, so that ``simulate``, the
integrators' consumers and the analyses can take a Scene without importing the builders.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from mslab.effects.base import Effect
from mslab.state import State
from mslab.system import System


def plural(n: int, word: str) -> str:
    """``"1 spring"``, ``"2 springs"``."""
    return f"{n} {word}{'' if n == 1 else 's'}"


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
        """Number of space dimensions (1, 2 or 3)."""
        return self.system.dim

    @property
    def n_particles(self) -> int:
        """Number of particles."""
        return self.system.n_particles

    @property
    def effects(self) -> list[str]:
        """Names of the effects the system evaluates."""
        return self.system.effect_names()

    def __repr__(self) -> str:
        """Return a one-line summary (name, size, effects, settings), never the arrays."""
        s = self.settings
        return (f"Scene({self.name!r}: {self.dim}D, {self.size_text()}, effects {self.effects}, "
                f"method={s.method!r}, dt={s.dt:g}, t_end={s.t_end:g}, save_every={s.save_every})")

    def springs(self) -> Effect | None:
        """Return the effect holding the scene's Hooke springs (capability ``hooke_springs``), if any."""
        return spring_effect(self.system.effects)

    def size_text(self) -> str:
        """``"2 particles, 1 spring"``: the scene's size in words, singular where it is one."""
        return f"{plural(self.n_particles, 'particle')}, {plural(len(self.spring_kind), 'spring')}"

    def summary(self) -> dict:
        """Size, effects and default run settings, as plain data (for tables and JSON)."""
        s = self.settings
        return {"scene": self.name, "description": self.description, "dim": self.dim,
                "n_particles": self.n_particles, "n_springs": len(self.spring_kind),
                "effects": self.effects, "method": s.method, "dt": s.dt, "t_end": s.t_end,
                "save_every": s.save_every}

    def with_settings(self, **changes) -> Scene:
        """Return a copy of the scene with some run settings replaced."""
        return replace(self, settings=replace(self.settings, **changes))


def spring_effect(effects: list[Effect]) -> Effect | None:
    """Return the first effect that declares Hooke springs (:meth:`Effect.hooke_springs`), or None."""
    return next((e for e in effects if e.hooke_springs() is not None), None)


def own_copy(scene: Scene) -> Scene:
    """Return a stepping session's deep copy of ``scene``, but keep a system whose forces a user replaced.

    A system with ``rhs``, ``acceleration`` or ``force`` replaced on the instance (say, to log
    calls) is stepped as given: a copy would keep calling the user's function, which calls the
    original system, so the copy's counters would miss every evaluation. Only such a system is
    shared with the user; everything else is copied (editing the scene changes nothing in a run).
    """
    import copy

    if {"rhs", "acceleration", "force"} & set(vars(scene.system)):
        return replace(copy.deepcopy(replace(scene, system=None)), system=scene.system)
    return copy.deepcopy(scene)
