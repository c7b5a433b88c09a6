"""Scene files: read a TOML scene (built-in name or path), validate it, build the Scene.

The format is described in ``docs/scenes.md``; the built-in scenes are the ``*.toml``
files next to this module. Only the effects a file lists are built: a file without
``[gravity]``, ``[damping]`` or ``[[colliders]]`` gives a System without them.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from mslab.errors import SceneError
from mslab.scenes.builder import Scene, SceneBuilder, Settings
from mslab.scenes.validate import check_scene, check_settings, parse_scene_text

#: folder of the built-in scene files
SCENE_DIR = Path(__file__).resolve().parent

#: run settings ``load_scene`` accepts as keyword overrides
OVERRIDES = ("method", "dt", "t_end", "save_every")


def scene_names() -> list[str]:
    """Names of the built-in scenes (the ``*.toml`` files shipped with mslab), sorted."""
    return sorted(p.stem for p in SCENE_DIR.glob("*.toml"))


def scene_path(name_or_path: str | Path) -> Path:
    """The file of a built-in scene name, or the given path.

    Raises
    ------
    SceneError
        Neither a built-in name nor an existing file (the nearest built-in name is suggested).
    """
    text = str(name_or_path)
    if text in scene_names():
        return SCENE_DIR / f"{text}.toml"
    path = Path(text)
    if path.is_file():
        return path
    import difflib

    close = difflib.get_close_matches(Path(text).stem, scene_names(), n=1)
    hint = f" (did you mean '{close[0]}'?)" if close else ""
    raise SceneError(
        "scene",
        f"no built-in scene or file called '{text}'{hint}; built-in scenes: {', '.join(scene_names())}",
        text,
    )


def read_scene_spec(name_or_path: str | Path) -> tuple[dict, str]:
    """Parse and validate a scene file; returns ``(spec, source)`` (see ``check_scene``)."""
    path = scene_path(name_or_path)
    source = str(path) if path.parent != SCENE_DIR else path.name
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise SceneError("file", f"not UTF-8 text ({err.reason})", source) from None
    doc = parse_scene_text(text, source)
    return check_scene(doc, source, default_name=path.stem), source


def build_scene(spec: dict, source: str | None = None) -> Scene:
    """Build a :class:`Scene` from a validated spec; only the listed effects are created."""
    b = SceneBuilder(spec["dim"])
    try:
        for body in spec["bodies"]:
            first = b.n_particles
            for x, m, pinned, v in zip(body["x"], body["mass"], body["pinned"], body["v"], strict=True):
                b.add_particle(x, mass=float(m), pinned=bool(pinned), velocity=v)
            for s in body["springs"]:
                for (i, j), rest in zip(s["pairs"], s["rest_length"], strict=True):
                    b.add_spring(
                        first + int(i),
                        first + int(j),
                        s["stiffness"],
                        rest_length=float(rest),
                        damping=s["damping"],
                        kind=s["kind"],
                    )
        if spec["gravity"] is not None:
            b.add_gravity(spec["gravity"])
        if spec["gamma"] is not None:
            b.add_damping(spec["gamma"])
        for col in spec["colliders"]:
            if col["type"] == "plane":
                b.add_plane(
                    col["normal"], col["offset"], col["stiffness"], col["friction"], col["slip_velocity"]
                )
            else:
                b.add_sphere(
                    col["center"], col["radius"], col["stiffness"], col["friction"], col["slip_velocity"]
                )
    except SceneError as err:  # the spec is checked, so this is a bug; still name the file
        raise SceneError(err.key, err.reason, source) from None
    run = dict(spec["run"])
    if "method" in run:
        from mslab.integrators.base import get_method

        run["method"] = get_method(run["method"]).name
    b.settings = replace(Settings(), **run)
    return b.build(spec["name"], spec["description"])


def load_scene(name_or_path: str | Path, **overrides) -> Scene:
    """Read a scene file (built-in name or path) and build it.

    Parameters
    ----------
    name_or_path : str or Path
        A name from :func:`scene_names` (``"chain"``) or the path of a TOML file.
    **overrides
        Run settings replacing the file's ``[run]`` values: ``method``, ``dt``, ``t_end``,
        ``save_every`` (``None`` values are ignored).

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        The file is missing, not valid TOML or not a valid scene; the message names the
        file, the key and the reason.
    """
    spec, source = read_scene_spec(name_or_path)
    given = {k: v for k, v in overrides.items() if v is not None}
    for key in given:
        if key not in OVERRIDES:
            raise SceneError(key, f"unknown override; valid: {', '.join(OVERRIDES)}", source)
    if given:
        if "save_every" in given and isinstance(given["save_every"], np.integer):
            given["save_every"] = int(given["save_every"])
        merged = {**spec["run"], **given}
        check_settings(
            given,
            source,
            dt=merged.get("dt", Settings.dt),
            t_end=merged.get("t_end", Settings.t_end),
            note=" (given as an override)",
        )
        if "method" in given:
            from mslab.integrators.base import get_method

            given["method"] = get_method(given["method"]).name
        spec = {**spec, "run": merged | given}
    return build_scene(spec, source)
