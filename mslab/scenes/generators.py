"""Scene geometry, defined once: chains, grids (cloth), lattices, their pinned sets and springs.

The Python factories (:func:`chain`, :func:`cloth`, :func:`lattice`) and the scene-file
generators (``generator = "chain"`` ...) use the same functions: :data:`GENERATORS` (the
keys each generator reads), :func:`generator_shape` (checks them), :func:`generated_positions`,
:func:`pin_set` and :func:`grid_springs`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from mslab.effects.schema import describe, integer, number, string, vector
from mslab.errors import SceneError
from mslab.scene import Scene
from mslab.scenes.builder import SceneBuilder
from mslab.scenes.oscillator import oscillator, oscillator_solution

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = ["GENERATORS", "PIN_SETS", "chain", "cloth", "generated_positions", "generator_shape",
           "grid_springs", "lattice", "oscillator", "oscillator_solution", "pin_set"]

#: particle generators and the keys each one reads (besides the keys every body takes)
GENERATORS: dict[str, tuple[str, ...]] = {
    "chain": ("n", "length"),
    "grid": ("nx", "ny", "size", "orientation"),
    "cloth": ("nx", "ny", "size", "orientation"),
    "lattice": ("n", "size"),
}
#: named pinned sets of each generator (besides plain indices)
PIN_SETS: dict[str | None, tuple[str, ...]] = {
    "chain": ("first", "last"),
    "grid": ("top_corners", "top_edge", "bottom_edge", "left_edge", "right_edge"),
    "cloth": ("top_corners", "top_edge", "bottom_edge", "left_edge", "right_edge"),
    "lattice": ("bottom",),
    None: (),
}


def generator_shape(generator: str, t: Mapping, prefix: str, dim: int) -> dict:
    """Check a generator's keys in table ``t``; returns ``shape``, ``length``, ``size``, ``orientation``.

    ``shape``: ``(n,)`` for a chain, ``(ny, nx)`` for a grid, ``(nx, ny, nz)`` for a lattice.
    Errors name ``prefix + key``.
    """
    if generator == "chain":
        shape: tuple[int, ...] = (integer(t.get("n", 10), f"{prefix}n", low=2),)
    elif generator in ("grid", "cloth"):
        if dim < 2:
            raise SceneError(f"{prefix}generator", f"'{generator}' needs dim 2 or 3, got dim = {dim}")
        nx = integer(t.get("nx", 10), f"{prefix}nx", low=2)
        shape = (integer(t.get("ny", 10), f"{prefix}ny", low=2), nx)
    else:
        if dim != 3:
            raise SceneError(f"{prefix}generator", f"'lattice' needs dim = 3, got dim = {dim}")
        n = t.get("n", [4, 4, 4])
        if not isinstance(n, list) or len(n) != 3:
            raise SceneError(f"{prefix}n",
                             f"must be a list of 3 whole numbers [nx, ny, nz], got {describe(n)}")
        shape = tuple(integer(k, f"{prefix}n[{i}]", low=2) for i, k in enumerate(n))
    length = number(t.get("length", 1.0), f"{prefix}length", low=0.0, strict=True)
    n_size = 2 if generator in ("grid", "cloth") else 3
    size_raw = t.get("size", 1.0)
    if isinstance(size_raw, list):
        size = vector(size_raw, f"{prefix}size", n_size)
        if np.any(size <= 0):
            raise SceneError(f"{prefix}size", "must be > 0")
    else:
        size = np.full(n_size, number(size_raw, f"{prefix}size", low=0.0, strict=True))
    orientation = string(t.get("orientation", "vertical"), f"{prefix}orientation", ("vertical", "horizontal"))
    return {"shape": shape, "length": length, "size": size, "orientation": orientation}


def generated_positions(generator: str, shape: tuple[int, ...], dim: int, length: float = 1.0,
                        size: npt.ArrayLike = (1.0, 1.0, 1.0), origin: npt.ArrayLike | None = None,
                        orientation: str = "vertical") -> np.ndarray:
    """Positions (n_particles, dim) of a generator, numbered in C order of ``shape``.

    ``chain``: along +x from the origin, ``length`` long. ``grid``/``cloth``: ``shape =
    (ny, nx)``, index ``j * nx + i``, x along i; j runs along the "up" axis (2D: y; 3D: z,
    a hanging cloth) or, ``orientation = "horizontal"`` in 3D, along y (a flat sheet);
    row ``j = ny - 1`` sits at the origin, the others at negative offsets down to ``-size[1]``.
    ``lattice``: ``shape = (nx, ny, nz)`` spanning ``size`` from the origin.
    """
    size = np.asarray(size, dtype=float)
    if generator == "chain":
        x = np.zeros((shape[0], dim))
        x[:, 0] = np.linspace(0.0, length, shape[0])
    elif generator in ("grid", "cloth"):
        ny, nx = shape
        gx, gy = np.meshgrid(np.linspace(0.0, size[0], nx), np.linspace(-size[1], 0.0, ny), indexing="xy")
        x = np.zeros((nx * ny, dim))
        x[:, 0] = gx.ravel()
        x[:, 1 if orientation == "horizontal" else dim - 1] = gy.ravel()
    else:
        axes = [np.linspace(0.0, s, k) for s, k in zip(size, shape, strict=True)]
        x = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return x if origin is None else x + np.asarray(origin, dtype=float)


def pin_set(generator: str, name: str, shape: tuple[int, ...]) -> list[int]:
    """Return the indices of a named pinned set of a generator (see :data:`PIN_SETS`)."""
    if name not in PIN_SETS[generator]:
        raise ValueError(f"generator '{generator}' has no pinned set '{name}'; "
                         f"valid: {', '.join(PIN_SETS[generator])}")
    index = np.arange(int(np.prod(shape))).reshape(shape)
    sets = {
        "first": lambda: [0],
        "last": lambda: [shape[0] - 1],
        "top_corners": lambda: [index[-1, 0], index[-1, -1]],
        "top_edge": lambda: index[-1, :].tolist(),
        "bottom_edge": lambda: index[0, :].tolist(),
        "left_edge": lambda: index[:, 0].tolist(),
        "right_edge": lambda: index[:, -1].tolist(),
        "bottom": lambda: index[:, :, 0].ravel().tolist(),
    }
    return [int(i) for i in sets[name]()]


def _offsets(ndim: int, kind: str) -> list[tuple[int, ...]]:
    """Neighbour offsets of a regular grid, one of each +/- pair (first non-zero > 0)."""
    import itertools

    out = []
    for o in itertools.product((-2, -1, 0, 1, 2), repeat=ndim):
        nz = [c for c in o if c != 0]
        if not nz or nz[0] < 0:
            continue
        if kind == "structural" and len(nz) == 1 and abs(nz[0]) == 1:
            out.append(o)
        elif kind == "shear" and len(nz) >= 2 and all(abs(c) == 1 for c in nz):
            out.append(o)
        elif kind == "bend" and len(nz) == 1 and abs(nz[0]) == 2:
            out.append(o)
    return out


def grid_springs(shape: tuple[int, ...], kind: str) -> np.ndarray:
    """Index pairs (n_springs, 2) of one spring kind on a regular grid of ``shape``.

    ``structural``: axis neighbours (resist stretching); ``shear``: diagonals (resist
    shearing; in 3D face and body diagonals); ``bend``: every second particle along an
    axis (resist bending). Particles are numbered in C order of ``shape``.
    """
    index = np.arange(int(np.prod(shape))).reshape(shape)
    pairs = []
    for o in _offsets(len(shape), kind):
        src = tuple(slice(max(0, -c), n - max(0, c)) for c, n in zip(o, shape, strict=True))
        dst = tuple(slice(max(0, c), n - max(0, -c)) for c, n in zip(o, shape, strict=True))
        pairs.append(np.stack([index[src].ravel(), index[dst].ravel()], axis=1))
    return np.concatenate(pairs) if pairs else np.empty((0, 2), dtype=np.int64)


def chain(n: int = 10, dim: int = 2, length: float = 1.0, mass: float = 1.0, stiffness: float = 100.0,
          damping: float = 0.0, gamma: float = 0.0, gravity: float | None = 9.81,
          pin: str = "first") -> Scene:
    """Build a chain of ``n`` particles on the x axis joined by structural springs.

    Parameters
    ----------
    n : int
        Number of particles (n - 1 springs).
    length, mass : float
        Total length and total mass (equal masses).
    stiffness, damping : float
        Spring stiffness k and damping c along each spring.
    gamma : float
        Viscous drag on every particle (0: none, the effect is not built).
    gravity : float or None
        Strength of gravity pulling down (-y in 2D, -z in 3D, -x in 1D); None or 0: no gravity effect.
    pin : {"first", "last", "both", "none"}
    """
    b = SceneBuilder(dim)
    pins = {"both": ["first", "last"], "none": []}.get(pin, [pin])
    pinned = {i for name in pins for i in pin_set("chain", name, (n,))}
    for i, pos in enumerate(generated_positions("chain", (n,), dim, length)):
        b.add_particle(pos, mass=mass / n, pinned=i in pinned)
    b.add_springs(grid_springs((n,), "structural"), stiffness, damping=damping)
    if gravity:
        b.add_gravity(gravity)
    if gamma:
        b.add_damping(gamma)
    b.set_run(method="rk4", dt=1e-3, t_end=2.0)
    return b.build("chain", f"chain of {n} particles, k = {stiffness:g}")


def cloth(nx: int = 10, ny: int = 10, size: float = 1.0, mass: float = 1.0,
          structural: float = 500.0, shear: float | None = 50.0, bend: float | None = 5.0,
          damping: float = 0.0, gamma: float = 0.0, gravity: float | None = 9.81,
          pin: str = "top_corners") -> Scene:
    """Build a square cloth of ``nx * ny`` particles in the x-z plane (3D), hanging from its top.

    Row ``j = ny - 1`` is the top edge (z = 0); the cloth hangs down to ``z = -size``.
    Spring kinds have their own stiffness; ``None`` (or 0) leaves a kind out.
    ``pin``: ``top_corners``, ``top_edge`` (or any grid pinned set) or ``none``.
    """
    b = SceneBuilder(3)
    shape = (ny, nx)
    b.add_particles(generated_positions("cloth", shape, 3, size=(size, size)), mass=mass / (nx * ny))
    for p in [] if pin == "none" else pin_set("cloth", pin, shape):
        b.pin(p)
    for kind, k in (("structural", structural), ("shear", shear), ("bend", bend)):
        if k:
            b.add_springs(grid_springs(shape, kind), k, damping=damping, kind=kind)
    if gravity:
        b.add_gravity(gravity)
    if gamma:
        b.add_damping(gamma)
    b.set_run(method="implicit_euler", dt=1e-2, t_end=2.0)
    return b.build("cloth", f"{nx}x{ny} cloth")


def lattice(n: tuple[int, int, int] = (4, 4, 4), size: float = 1.0, mass: float = 1.0,
            structural: float = 500.0, shear: float | None = 200.0, bend: float | None = None,
            damping: float = 0.0, gamma: float = 0.0,
            origin: npt.ArrayLike = (0.0, 0.0, 0.0)) -> Scene:
    """Build a 3D block of particles (a soft body) with structural, shear and bend springs."""
    b = SceneBuilder(3)
    grid = generated_positions("lattice", tuple(n), 3, size=(size, size, size), origin=origin)
    b.add_particles(grid, mass=mass / grid.shape[0])
    for kind, k in (("structural", structural), ("shear", shear), ("bend", bend)):
        if k:
            b.add_springs(grid_springs(tuple(n), kind), k, damping=damping, kind=kind)
    if gamma:
        b.add_damping(gamma)
    b.set_run(method="implicit_euler", dt=5e-3, t_end=2.0)
    return b.build("lattice", f"{n[0]}x{n[1]}x{n[2]} lattice")
