"""Scene-file schema and validation: every mistake becomes one :class:`~mslab.errors.SceneError`.

A scene file is TOML (format: ``docs/scenes.md``). :func:`parse_scene_text` reads it and
:func:`check_scene` turns the raw tables into a *spec*: plain dicts and numpy arrays whose
every value has been checked (types, finite numbers, signs, index ranges, lengths),
so the loader can build the scene without further questions. Errors name the file,
the dotted key (``springs.structural.stiffness``, ``colliders[0].radius``) and the
reason; an unknown key or section comes with the nearest valid name.
"""

from __future__ import annotations

import difflib
import re
import tomllib

import numpy as np

from mslab.errors import SceneError

#: top-level sections of a scene file
SECTIONS = ("scene", "particles", "springs", "bodies", "gravity", "damping", "colliders", "run")
#: spring kinds (sub-tables of ``[springs]``)
SPRING_KINDS = ("structural", "shear", "bend")
#: particle generators and the keys each one reads (besides the common keys)
GENERATORS = {
    "chain": ("n", "length"),
    "grid": ("nx", "ny", "size", "orientation"),
    "cloth": ("nx", "ny", "size", "orientation"),
    "lattice": ("n", "size"),
}
#: named pinned sets per generator (besides plain indices)
PIN_SETS = {
    "chain": ("first", "last"),
    "grid": ("top_corners", "top_edge", "bottom_edge", "left_edge", "right_edge"),
    "cloth": ("top_corners", "top_edge", "bottom_edge", "left_edge", "right_edge"),
    "lattice": ("bottom",),
    None: (),
}
_COMMON_PARTICLE_KEYS = (
    "generator",
    "positions",
    "mass",
    "total_mass",
    "pinned",
    "velocity",
    "velocities",
    "origin",
)
PARTICLE_KEYS = tuple(
    dict.fromkeys(_COMMON_PARTICLE_KEYS + ("n", "length", "nx", "ny", "size", "orientation"))
)
SPRING_KEYS = ("stiffness", "damping", "rest_length", "pairs")
KEYS = {
    "scene": ("name", "description", "dim"),
    "gravity": ("g",),
    "damping": ("gamma",),
    "run": ("method", "dt", "t_end", "save_every"),
    "plane": ("type", "normal", "offset", "stiffness", "friction", "slip_velocity"),
    "sphere": ("type", "center", "radius", "stiffness", "friction", "slip_velocity"),
}


def _suggest(word: str, valid) -> str:
    close = difflib.get_close_matches(str(word), list(valid), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def parse_scene_text(text: str, source: str | None = None) -> dict:
    """Parse TOML text; a syntax error becomes ``SceneError("line N", ...)``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        msg = str(err)
        match = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        reason = re.sub(r"\s*\(at line \d+, column \d+\)", "", msg) or "invalid TOML"
        if match:
            key = f"line {match.group(1)}"
            reason = f"TOML syntax error: {reason} (column {match.group(2)})"
        elif "end of document" in msg:
            reason = re.sub(r"\s*\(at end of document\)", "", msg)
            key = f"line {len(text.rstrip().splitlines())}"
            reason = f"TOML syntax error: {reason} (at the end of the file)"
        else:
            key, reason = "toml", f"TOML syntax error: {reason}"
        raise SceneError(key, reason, source) from None


class _Checker:
    """Typed reads from the raw TOML tables, raising SceneError with file and key."""

    def __init__(self, source: str | None):
        self.source = source

    def fail(self, key: str, reason: str):
        raise SceneError(key, reason, self.source)

    def keys(self, table: dict, valid, prefix: str, what: str = "key") -> None:
        for k in table:
            if k not in valid:
                self.fail(
                    f"{prefix}{k}", f"unknown {what}{_suggest(k, valid)}; valid {what}s: {', '.join(valid)}"
                )

    def table(self, value, key: str) -> dict:
        if not isinstance(value, dict):
            self.fail(key, f"must be a table ([{key}]), got {_kind(value)}")
        return value

    def number(self, value, key: str, *, low: float | None = None, strict: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(key, f"must be a number, got {_kind(value)}")
        value = float(value)
        if not np.isfinite(value):
            self.fail(key, f"must be a finite number, got {value}")
        if low is not None and (value <= low if strict else value < low):
            self.fail(key, f"must be {'>' if strict else '>='} {low:g}, got {value:g}")
        return value

    def integer(self, value, key: str, *, low: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"must be a whole number, got {_kind(value)}")
        if low is not None and value < low:
            self.fail(key, f"must be >= {low}, got {value}")
        return int(value)

    def string(self, value, key: str, choices=None) -> str:
        if not isinstance(value, str):
            self.fail(key, f"must be a string, got {_kind(value)}")
        if choices is not None and value not in choices:
            self.fail(key, f"unknown value '{value}'{_suggest(value, choices)}; valid: {', '.join(choices)}")
        return value

    def vector(self, value, key: str, dim: int) -> np.ndarray:
        if not isinstance(value, list) or len(value) != dim:
            self.fail(key, f"must be a list of {dim} numbers, got {_kind(value)}")
        return np.array([self.number(c, f"{key}[{i}]") for i, c in enumerate(value)])

    def vectors(self, value, key: str, dim: int, n: int | None = None) -> np.ndarray:
        if not isinstance(value, list) or not value:
            self.fail(key, f"must be a non-empty list of {dim}-vectors, got {_kind(value)}")
        if n is not None and len(value) != n:
            self.fail(key, f"must have one entry per particle ({n}), got {len(value)}")
        return np.array([self.vector(p, f"{key}[{i}]", dim) for i, p in enumerate(value)]).reshape(-1, dim)

    def numbers(
        self, value, key: str, n: int, *, low: float | None = None, strict: bool = False
    ) -> np.ndarray:
        """One number for all, or a list of ``n`` numbers."""
        if isinstance(value, list):
            if len(value) != n:
                self.fail(key, f"must be one number or a list of {n} numbers, got a list of {len(value)}")
            return np.array(
                [self.number(c, f"{key}[{i}]", low=low, strict=strict) for i, c in enumerate(value)]
            )
        return np.full(n, self.number(value, key, low=low, strict=strict))

    def index(self, value, key: str, n: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"particle index must be a whole number, got {_kind(value)}")
        if not 0 <= value < n:
            self.fail(key, f"particle index {value} out of range 0..{n - 1}")
        return int(value)


def _kind(value) -> str:
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"the string '{value}'"
    if isinstance(value, int | float):
        return f"the number {value}"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    if isinstance(value, dict):
        return "a table"
    return type(value).__name__


# -- particles ----------------------------------------------------------------------------------------
def _grid_shape(c: _Checker, t: dict, p: str, generator: str, dim: int) -> tuple[int, ...]:
    if generator == "chain":
        return (c.integer(t.get("n", 10), f"{p}n", low=2),)
    if generator in ("grid", "cloth"):
        if dim < 2:
            c.fail(f"{p}generator", f"'{generator}' needs dim 2 or 3, got dim = {dim}")
        nx = c.integer(t.get("nx", 10), f"{p}nx", low=2)
        ny = c.integer(t.get("ny", 10), f"{p}ny", low=2)
        return (ny, nx)
    if dim != 3:
        c.fail(f"{p}generator", f"'lattice' needs dim = 3, got dim = {dim}")
    n = t.get("n", [4, 4, 4])
    if not isinstance(n, list) or len(n) != 3:
        c.fail(f"{p}n", f"must be a list of 3 whole numbers [nx, ny, nz], got {_kind(n)}")
    return tuple(c.integer(k, f"{p}n[{i}]", low=2) for i, k in enumerate(n))


def generated_positions(
    generator: str,
    shape: tuple[int, ...],
    dim: int,
    length: float,
    size: np.ndarray,
    origin: np.ndarray,
    orientation: str = "vertical",
) -> np.ndarray:
    """Positions (n_particles, dim) of a generator, numbered in C order of ``shape``.

    ``chain``: along +x from the origin, ``length`` long. ``grid``/``cloth``: ``shape =
    (ny, nx)``, index ``j * nx + i``, x along i; j runs along the last axis (2D: y; 3D: z,
    a hanging cloth) or, ``orientation = "horizontal"`` in 3D, along y (a flat sheet);
    row ``j = ny - 1`` sits at the origin, the others at negative offsets down to ``-size[1]``.
    ``lattice``: ``shape = (nx, ny, nz)`` spanning ``size`` from the origin.
    """
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
    return x + origin


def pin_set(generator: str, name: str, shape: tuple[int, ...]) -> list[int]:
    """Indices of a named pinned set (``first``, ``top_corners``, ``bottom`` ...)."""
    index = np.arange(int(np.prod(shape))).reshape(shape)
    sets = {
        "first": [0],
        "last": [shape[0] - 1],
        "top_corners": [int(index[-1, 0]), int(index[-1, -1])] if len(shape) == 2 else [],
        "top_edge": index[-1, :].tolist() if len(shape) == 2 else [],
        "bottom_edge": index[0, :].tolist() if len(shape) == 2 else [],
        "left_edge": index[:, 0].tolist() if len(shape) == 2 else [],
        "right_edge": index[:, -1].tolist() if len(shape) == 2 else [],
        "bottom": index[:, :, 0].ravel().tolist() if len(shape) == 3 else [],
    }
    return [int(i) for i in sets[name]]


def _check_particles(c: _Checker, t: dict, p: str, dim: int) -> dict:
    """Validate one body's particle keys (prefix ``p`` like ``particles.``)."""
    generator = t.get("generator")
    if generator is not None:
        generator = c.string(generator, f"{p}generator", tuple(GENERATORS))
        if "positions" in t:
            c.fail(
                f"{p}positions", f"give either a generator or positions, not both (generator = '{generator}')"
            )
        for k in t:
            if k not in _COMMON_PARTICLE_KEYS and k not in GENERATORS[generator]:
                c.fail(
                    f"{p}{k}",
                    f"not used by generator '{generator}' (its keys: {', '.join(GENERATORS[generator])})",
                )
        shape = _grid_shape(c, t, p, generator, dim)
        length = c.number(t.get("length", 1.0), f"{p}length", low=0.0, strict=True)
        size_raw = t.get("size", 1.0)
        n_size = 2 if generator in ("grid", "cloth") else 3
        size = (
            c.vector(size_raw, f"{p}size", n_size)
            if isinstance(size_raw, list)
            else np.full(n_size, c.number(size_raw, f"{p}size", low=0.0, strict=True))
        )
        if np.any(size <= 0):
            c.fail(f"{p}size", "must be > 0")
        origin = c.vector(t["origin"], f"{p}origin", dim) if "origin" in t else np.zeros(dim)
        orientation = c.string(
            t.get("orientation", "vertical"), f"{p}orientation", ("vertical", "horizontal")
        )
        x = generated_positions(generator, shape, dim, length, size, origin, orientation)
    else:
        if "positions" not in t:
            c.fail(
                f"{p}positions",
                "missing: give a generator (chain, grid, cloth, lattice) or a list of positions",
            )
        for k in t:
            if k not in _COMMON_PARTICLE_KEYS:
                c.fail(f"{p}{k}", "only used with a generator; this body lists explicit positions")
        if "origin" in t:
            c.fail(f"{p}origin", "only used with a generator")
        x = c.vectors(t["positions"], f"{p}positions", dim)
        shape = (x.shape[0],)
    n = x.shape[0]

    if "mass" in t and "total_mass" in t:
        c.fail(f"{p}total_mass", "give either mass (per particle) or total_mass, not both")
    if "total_mass" in t:
        mass = np.full(n, c.number(t["total_mass"], f"{p}total_mass", low=0.0, strict=True) / n)
    else:
        mass = c.numbers(t.get("mass", 1.0), f"{p}mass", n, low=0.0, strict=True)

    pinned = np.zeros(n, dtype=bool)
    pins = t.get("pinned", [])
    if not isinstance(pins, list):
        pins = [pins]
    for q, item in enumerate(pins):
        if isinstance(item, str):
            c.string(item, f"{p}pinned[{q}]", PIN_SETS[generator] or ("(none: use indices)",))
            pinned[pin_set(generator, item, shape)] = True
        else:
            pinned[c.index(item, f"{p}pinned[{q}]", n)] = True

    if "velocity" in t and "velocities" in t:
        c.fail(f"{p}velocities", "give either velocity (one for all) or velocities (one per particle)")
    if "velocities" in t:
        v = c.vectors(t["velocities"], f"{p}velocities", dim, n)
    elif "velocity" in t:
        v = np.tile(c.vector(t["velocity"], f"{p}velocity", dim), (n, 1))
    else:
        v = np.zeros((n, dim))
    v[pinned] = 0.0
    return {"generator": generator, "shape": shape, "x": x, "mass": mass, "pinned": pinned, "v": v}


def _check_springs(c: _Checker, table, p: str, body: dict) -> list[dict]:
    """Validate ``[springs.<kind>]`` sub-tables against one body's particles."""
    from mslab.scenes.generators import grid_springs

    table = c.table(table, p.rstrip("."))
    c.keys(table, SPRING_KINDS, p, "spring kind")
    x, n, generator = body["x"], body["x"].shape[0], body["generator"]
    out = []
    for kind, t in table.items():
        q = f"{p}{kind}."
        t = c.table(t, q.rstrip("."))
        c.keys(t, SPRING_KEYS, q)
        if "stiffness" not in t:
            c.fail(f"{q}stiffness", "missing (spring stiffness k in N/m)")
        stiffness = c.number(t["stiffness"], f"{q}stiffness", low=0.0)
        damping = c.number(t.get("damping", 0.0), f"{q}damping", low=0.0)
        if "pairs" in t:
            raw = t["pairs"]
            if not isinstance(raw, list) or not raw:
                c.fail(f"{q}pairs", f"must be a non-empty list of [i, j] index pairs, got {_kind(raw)}")
            pairs = []
            for s, pair in enumerate(raw):
                if not isinstance(pair, list) or len(pair) != 2:
                    c.fail(f"{q}pairs[{s}]", f"must be a pair [i, j], got {_kind(pair)}")
                i, j = (c.index(k, f"{q}pairs[{s}]", n) for k in pair)
                if i == j:
                    c.fail(f"{q}pairs[{s}]", f"a spring needs two different particles, got [{i}, {j}]")
                pairs.append((i, j))
            pairs = np.array(pairs, dtype=np.int64)
        elif generator is None:
            c.fail(f"{q}pairs", "missing: with explicit positions, list the springs as pairs = [[i, j], ...]")
        else:
            pairs = grid_springs(body["shape"], kind).astype(np.int64)
            if pairs.shape[0] == 0:
                c.fail(f"springs.{kind}", f"generator '{generator}' has no {kind} springs")
        lengths = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
        if "rest_length" in t:
            rest = c.numbers(t["rest_length"], f"{q}rest_length", pairs.shape[0], low=0.0)
        else:
            zero = np.flatnonzero(lengths == 0.0)
            if zero.size:
                i, j = pairs[zero[0]]
                c.fail(
                    f"{q}rest_length",
                    f"spring [{i}, {j}] has zero length in the initial positions, so its "
                    "rest length cannot be taken from them; give rest_length explicitly",
                )
            rest = lengths
        out.append(
            {"kind": kind, "pairs": pairs, "stiffness": stiffness, "damping": damping, "rest_length": rest}
        )
    return out


# -- whole file ---------------------------------------------------------------------------------------
def check_scene(doc: dict, source: str | None = None, default_name: str = "scene") -> dict:
    """Validate a parsed scene file; return its spec (every value checked).

    Returns
    -------
    dict with ``name``, ``description``, ``dim``, ``bodies`` (list of dicts with ``x``,
    ``v`` (n, dim), ``mass``, ``pinned`` (n,), ``springs``: list of per-kind dicts),
    ``gravity`` (vector or None), ``gamma`` (float or None), ``colliders`` (list of
    dicts), ``run`` (dict of the settings given).

    Raises
    ------
    SceneError
        The first problem found, naming the key.
    """
    from mslab.scenes.builder import Settings

    c = _Checker(source)
    c.keys(doc, SECTIONS, "", "section")

    scene = c.table(doc.get("scene", {}), "scene")
    c.keys(scene, KEYS["scene"], "scene.")
    name = c.string(scene.get("name", default_name), "scene.name")
    description = c.string(scene.get("description", ""), "scene.description")
    dim = c.integer(scene.get("dim", 2), "scene.dim")
    if dim not in (1, 2, 3):
        c.fail("scene.dim", f"must be 1, 2 or 3, got {dim}")

    raw_bodies = []
    if "bodies" in doc:
        if "particles" in doc or "springs" in doc:
            c.fail("bodies", "use either [particles] + [springs.*] (one body) or [[bodies]], not both")
        if not isinstance(doc["bodies"], list) or not doc["bodies"]:
            c.fail("bodies", "must be an array of tables: write [[bodies]] once per body")
        for b, t in enumerate(doc["bodies"]):
            t = c.table(t, f"bodies[{b}]")
            springs = t.get("springs")
            raw_bodies.append(({k: val for k, val in t.items() if k != "springs"}, springs, f"bodies[{b}]."))
    else:
        if "particles" not in doc:
            c.fail("particles", "missing: a scene needs a [particles] section (or [[bodies]])")
        raw_bodies.append((c.table(doc["particles"], "particles"), doc.get("springs"), "particles."))
    bodies = []
    for particles, springs, p in raw_bodies:
        c.keys(particles, PARTICLE_KEYS + (("springs",) if p.startswith("bodies") else ()), p)
        body = _check_particles(c, particles, p, dim)
        sp = "springs." if p == "particles." else f"{p}springs."
        body["springs"] = [] if springs is None else _check_springs(c, springs, sp, body)
        bodies.append(body)

    gravity = None
    if "gravity" in doc:
        t = c.table(doc["gravity"], "gravity")
        c.keys(t, KEYS["gravity"], "gravity.")
        if "g" not in t:
            c.fail("gravity.g", "missing: a number (strength, pointing down the last axis) or a vector")
        if isinstance(t["g"], list):
            gravity = c.vector(t["g"], "gravity.g", dim)
        else:
            gravity = np.zeros(dim)
            gravity[dim - 1] = -c.number(t["g"], "gravity.g")

    gamma = None
    if "damping" in doc:
        t = c.table(doc["damping"], "damping")
        c.keys(t, KEYS["damping"], "damping.")
        if "gamma" not in t:
            c.fail("damping.gamma", "missing (drag coefficient in kg/s: f = -gamma v)")
        gamma = c.number(t["gamma"], "damping.gamma", low=0.0)

    colliders = []
    if "colliders" in doc:
        raw = doc["colliders"]
        if not isinstance(raw, list):
            c.fail("colliders", "must be an array of tables: write [[colliders]] once per collider")
        for q, t in enumerate(raw):
            p = f"colliders[{q}]."
            t = c.table(t, p.rstrip("."))
            if "type" not in t:
                c.fail(f"{p}type", "missing: 'plane' or 'sphere'")
            kind = c.string(t["type"], f"{p}type", ("plane", "sphere"))
            c.keys(t, KEYS[kind], p)
            for key in KEYS[kind][1:4]:
                if key not in t:
                    c.fail(f"{p}{key}", f"missing (a {kind} needs {', '.join(KEYS[kind][1:4])})")
            col = {
                "type": kind,
                "stiffness": c.number(t["stiffness"], f"{p}stiffness", low=0.0, strict=True),
                "friction": c.number(t.get("friction", 0.0), f"{p}friction", low=0.0),
                "slip_velocity": c.number(
                    t.get("slip_velocity", 1e-3), f"{p}slip_velocity", low=0.0, strict=True
                ),
            }
            if kind == "plane":
                col["normal"] = c.vector(t["normal"], f"{p}normal", dim)
                if not np.any(col["normal"]):
                    c.fail(f"{p}normal", "must not be the zero vector")
                col["offset"] = c.number(t["offset"], f"{p}offset")
            else:
                col["center"] = c.vector(t["center"], f"{p}center", dim)
                col["radius"] = c.number(t["radius"], f"{p}radius", low=0.0, strict=True)
            colliders.append(col)

    run = c.table(doc.get("run", {}), "run")
    c.keys(run, KEYS["run"], "run.")
    settings = {}
    if "method" in run:
        settings["method"] = c.string(run["method"], "run.method")
    if "dt" in run:
        settings["dt"] = c.number(run["dt"], "run.dt", low=0.0, strict=True)
    if "t_end" in run:
        settings["t_end"] = c.number(run["t_end"], "run.t_end", low=0.0, strict=True)
    if "save_every" in run:
        settings["save_every"] = c.integer(run["save_every"], "run.save_every", low=1)
    check_settings(settings, source, dt=Settings.dt, t_end=Settings.t_end)
    return {
        "name": name,
        "description": description,
        "dim": dim,
        "bodies": bodies,
        "gravity": gravity,
        "gamma": gamma,
        "colliders": colliders,
        "run": settings,
    }


def check_settings(settings: dict, source: str | None = None, *, dt=None, t_end=None, note: str = "") -> None:
    """Check run settings (given in the file or as overrides): method known, dt and t_end > 0,
    ``t_end / dt`` a whole number of steps (with ``dt``/``t_end`` defaults filled in by the caller)."""
    from mslab.integrators.base import get_method
    from mslab.simulate import step_count

    c = _Checker(source)
    if "method" in settings:
        try:
            get_method(c.string(settings["method"], "run.method"))
        except ValueError as err:
            c.fail("run.method", f"{err}{note}")
    for key in ("dt", "t_end"):
        if key in settings:
            value = settings[key]
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not np.isfinite(value)
                or value <= 0
            ):
                c.fail(f"run.{key}", f"must be a finite number > 0, got {value!r}{note}")
    if "save_every" in settings:
        value = settings["save_every"]
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            c.fail("run.save_every", f"must be a whole number >= 1, got {value!r}{note}")
    dt = settings.get("dt", dt)
    t_end = settings.get("t_end", t_end)
    if dt is not None and t_end is not None:
        try:
            step_count(float(t_end), float(dt))
        except ValueError as err:
            c.fail("run.dt" if "dt" in settings else "run.t_end", f"{err}{note}")
