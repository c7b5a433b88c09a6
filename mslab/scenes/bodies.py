"""The particles of a scene file: ``[particles]`` or one ``[[bodies]]`` entry per body.

Positions come from a generator of :mod:`mslab.scenes.generators` (the only definition of
the scene geometry and of the named pinned sets) or are listed; masses, pins and
velocities are checked and the particles added to the builder. Each body's own effect
sections (springs) are read by their effect modules against the :class:`Body` record.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from mslab.effects.schema import index, number, numbers, string, vector, vectors
from mslab.errors import SceneError
from mslab.scenes.builder import SceneBuilder
from mslab.scenes.generators import (
    GENERATORS,
    PIN_SETS,
    generated_positions,
    generator_shape,
    grid_springs,
    pin_set,
)

#: keys every body takes, with or without a generator
COMMON_KEYS = ("generator", "positions", "mass", "total_mass", "pinned", "velocity", "velocities", "origin")
#: every particle key (the common ones and those of the generators)
PARTICLE_KEYS = tuple(dict.fromkeys(COMMON_KEYS + tuple(k for keys in GENERATORS.values() for k in keys)))


@dataclass(frozen=True)
class Body:
    """One body of a scene file, as its effect sections see it.

    Attributes
    ----------
    first : int
        Scene index of the body's first particle (indices in the file count within the body).
    n : int
        Number of particles.
    generator : str or None
    shape : tuple of int
        Generator shape (``(n,)`` for listed positions).
    """

    first: int
    n: int
    generator: str | None
    shape: tuple[int, ...]

    def generated_pairs(self, kind: str) -> np.ndarray:
        """Index pairs (within the body) of one spring kind of the body's generator."""
        return grid_springs(self.shape, kind).astype(np.int64)


def add_body(builder: SceneBuilder, t: Mapping, p: str) -> Body:
    """Check one body's particle keys (prefix ``p``, e.g. ``particles.``) and add its particles."""
    dim = builder.dim
    generator = t.get("generator")
    if generator is not None:
        generator = string(generator, f"{p}generator", tuple(GENERATORS))
        if "positions" in t:
            raise SceneError(f"{p}positions", f"give either a generator or positions, not both "
                             f"(generator = '{generator}')")
        for k in t:
            if k not in COMMON_KEYS and k not in GENERATORS[generator]:
                raise SceneError(f"{p}{k}", f"not used by generator '{generator}' "
                                 f"(its keys: {', '.join(GENERATORS[generator])})")
        g = generator_shape(generator, t, p, dim)
        origin = vector(t["origin"], f"{p}origin", dim) if "origin" in t else np.zeros(dim)
        shape = g["shape"]
        x = generated_positions(generator, shape, dim, g["length"], g["size"], origin, g["orientation"])
    else:
        if "positions" not in t:
            raise SceneError(f"{p}positions", f"missing: give a generator ({', '.join(GENERATORS)}) "
                             "or a list of positions")
        for k in t:
            if k not in COMMON_KEYS:
                raise SceneError(f"{p}{k}", "only used with a generator; this body lists explicit positions")
        if "origin" in t:
            raise SceneError(f"{p}origin", "only used with a generator")
        x = vectors(t["positions"], f"{p}positions", dim)
        shape = (x.shape[0],)
    n = x.shape[0]

    if "mass" in t and "total_mass" in t:
        raise SceneError(f"{p}total_mass", "give either mass (per particle) or total_mass, not both")
    if "total_mass" in t:
        mass = np.full(n, number(t["total_mass"], f"{p}total_mass", low=0.0, strict=True) / n)
    else:
        mass = numbers(t.get("mass", 1.0), f"{p}mass", n, low=0.0, strict=True)

    pinned = np.zeros(n, dtype=bool)
    pins = t.get("pinned", [])
    for q, item in enumerate(pins if isinstance(pins, list) else [pins]):
        if isinstance(item, str):
            string(item, f"{p}pinned[{q}]", PIN_SETS[generator] or ("(none: use indices)",))
            pinned[pin_set(generator, item, shape)] = True
        else:
            pinned[index(item, f"{p}pinned[{q}]", n)] = True

    if "velocity" in t and "velocities" in t:
        raise SceneError(f"{p}velocities",
                         "give either velocity (one for all) or velocities (one per particle)")
    if "velocities" in t:
        v = vectors(t["velocities"], f"{p}velocities", dim, n)
    elif "velocity" in t:
        v = np.tile(vector(t["velocity"], f"{p}velocity", dim), (n, 1))
    else:
        v = np.zeros((n, dim))
    first = builder.n_particles
    for xi, m, pin, vi in zip(x, mass, pinned, v, strict=True):
        builder.add_particle(xi, mass=float(m), pinned=bool(pin), velocity=vi)
    return Body(first, n, generator, shape)
