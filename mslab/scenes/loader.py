"""Scene files: find a TOML scene (built-in name or path), read it, check and build the Scene.

The format is described in ``docs/scenes.md``; the built-in scenes are the ``*.toml``
files next to this module. Only the effects a file lists are built: a file without
``[gravity]``, ``[damping]`` or ``[[colliders]]`` gives a System without them.
"""

from __future__ import annotations

import difflib
from pathlib import Path

import numpy as np

from mslab.checks import whole
from mslab.errors import SceneError
from mslab.scene import Scene, Settings
from mslab.scenes.settings import RUN_KEYS, check_settings
from mslab.scenes.toml_read import read_scene_file
from mslab.scenes.validate import scene_from_doc

#: folder of the built-in scene files
SCENE_DIR = Path(__file__).resolve().parent

#: run settings ``load_scene`` accepts as keyword overrides
OVERRIDES = RUN_KEYS


def scene_names() -> list[str]:
    """Names of the built-in scenes (the ``*.toml`` files shipped with mslab), sorted."""
    return sorted(p.stem for p in SCENE_DIR.glob("*.toml"))


def scene_path(name_or_path: str | Path) -> Path:
    """Return the file of a built-in scene name, or the given path.

    Raises
    ------
    SceneError
        A directory, or neither a built-in name nor an existing file (the nearest
        built-in name is suggested).
    """
    text = str(name_or_path)
    if text in scene_names():
        return SCENE_DIR / f"{text}.toml"
    path = Path(text)
    if path.is_file():
        return path
    if path.is_dir():
        raise SceneError("scene", f"'{text}' is a directory, not a scene file; give a .toml file inside it "
                         "or a built-in scene name", text)
    other = _not_a_file(path)
    if other:
        raise SceneError("scene", f"'{text}' {other}; give a regular .toml file or a built-in scene name",
                         text)
    close = difflib.get_close_matches(Path(text).stem, scene_names(), n=1)
    hint = f" (did you mean '{close[0]}'?)" if close else ""
    raise SceneError(
        "scene",
        f"no built-in scene or file called '{text}'{hint}; built-in scenes: {', '.join(scene_names())}",
        text,
    )


def _not_a_file(path: Path) -> str | None:
    """Say what ``path`` is when it exists but is no regular file (a FIFO, a device, a symlink loop)."""
    import os
    import stat

    try:
        mode = os.stat(path).st_mode
    except OSError as err:
        if not os.path.islink(path):
            return None
        if err.errno == 40:  # ELOOP
            return "is a symbolic link that leads back to itself (a loop)"
        return f"is a symbolic link to '{os.readlink(path)}', which does not exist"
    kinds = ((stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISSOCK, "a socket"),
             (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))
    for test, kind in kinds:
        if test(mode):
            return f"is {kind}, not a regular file (it is not read: that could wait forever)"
    return None


def load_scene(name_or_path: str | Path, *, max_bytes: int | None = None, **overrides) -> Scene:
    """Read a scene file (built-in name or path) and build it.

    Parameters
    ----------
    name_or_path : str or Path
        A name from :func:`scene_names` (``"chain"``) or the path of a TOML file.
    max_bytes : int, optional
        Memory the scene may take to build and run (default: the machine's memory); a
        generator making more particles is refused before they are made.
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
    if max_bytes is not None:
        max_bytes = whole("max_bytes", max_bytes, 1)
    path = scene_path(name_or_path)
    source = str(path) if path.parent != SCENE_DIR else path.name
    doc = read_scene_file(path, source)
    given = {k: v for k, v in overrides.items() if v is not None}
    for key in given:
        if key not in OVERRIDES:
            raise SceneError(key, f"unknown override; valid: {', '.join(OVERRIDES)}", source)
    if "save_every" in given and isinstance(given["save_every"], np.integer):
        given["save_every"] = int(given["save_every"])
    if given:
        run = doc.get("run", {}) if isinstance(doc.get("run", {}), dict) else {}

        def file_value(key: str, default: float) -> float:
            value = run.get(key)
            number = isinstance(value, int | float) and not isinstance(value, bool)
            return float(value) if number and np.isfinite(value) and value > 0 else default

        check_settings(given, source, dt=file_value("dt", Settings.dt),
                       t_end=file_value("t_end", Settings.t_end), note=" (given as an override)")
        given.update({k: float(given[k]) for k in ("dt", "t_end") if k in given})  # not a numpy float
    return scene_from_doc(doc, source, default_name=path.stem, overrides=given, max_bytes=max_bytes)
