"""A parsed scene file to a :class:`~mslab.scenes.builder.Scene`: every mistake is one ``SceneError``.

The file's tables are checked while the scene is built through the ``SceneBuilder``:
``[scene]`` here, the particles by :mod:`mslab.scenes.bodies`, the effect sections by their
effect modules (:mod:`mslab.scenes.sections`, driven by the effect registry), ``[run]`` by
:mod:`mslab.scenes.settings`. Errors name the file, the dotted key
(``springs.structural.stiffness``, ``colliders[0].radius``) and the reason; an unknown key or
section comes with the nearest valid name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from mslab.effects.schema import check_keys, integer, string
from mslab.errors import SceneError
from mslab.scene import Scene, Settings
from mslab.scenes.bodies import PARTICLE_KEYS, add_body
from mslab.scenes.builder import SceneBuilder
from mslab.scenes.sections import add_body_effects, add_scene_effects, body_sections, scene_sections
from mslab.scenes.settings import canonical, read_run

#: keys of ``[scene]``
SCENE_KEYS = ("name", "description", "dim")


def sections() -> tuple[str, ...]:
    """Every valid top-level section of a scene file."""
    return ("scene", "particles", *body_sections(), "bodies", *scene_sections(), "run")


def scene_from_doc(doc: Mapping, source: str | None = None, default_name: str = "scene",
                   overrides: Mapping | None = None) -> Scene:
    """Check a parsed scene file and build it; ``overrides`` replace ``[run]`` values (checked by the caller).

    Raises
    ------
    SceneError
        The first problem found, naming the file (``source``) and the key.
    """
    try:
        return _build(doc, default_name, overrides or {})
    except SceneError as err:
        if err.source is not None:
            raise
        raise SceneError(err.key, err.reason, source) from None


def _build(doc: Mapping, default_name: str, overrides: Mapping) -> Scene:
    check_keys(doc, sections(), "", "section")
    scene = SceneBuilder.check_table(doc.get("scene", {}), "scene")
    check_keys(scene, SCENE_KEYS, "scene.")
    name = string(scene.get("name", default_name), "scene.name")
    description = string(scene.get("description", ""), "scene.description")
    dim = integer(scene.get("dim", 2), "scene.dim")
    if dim not in (1, 2, 3):
        raise SceneError("scene.dim", f"must be 1, 2 or 3, got {dim}")
    builder = SceneBuilder(dim)

    per_body = body_sections()
    if "bodies" in doc:
        if "particles" in doc or any(s in doc for s in per_body):
            raise SceneError("bodies", f"use either [particles] + [{per_body[0]}.*] (one body) "
                             "or [[bodies]], not both")
        if not isinstance(doc["bodies"], list) or not doc["bodies"]:
            raise SceneError("bodies", "must be an array of tables: write [[bodies]] once per body")
        for b, table in enumerate(doc["bodies"]):
            p = f"bodies[{b}]."
            table = SceneBuilder.check_table(table, p.rstrip("."))
            check_keys(table, PARTICLE_KEYS + tuple(per_body), p)
            body = add_body(builder, {k: v for k, v in table.items() if k not in per_body}, p)
            add_body_effects(builder, table, body, p)
    else:
        if "particles" not in doc:
            raise SceneError("particles", "missing: a scene needs a [particles] section (or [[bodies]])")
        particles = SceneBuilder.check_table(doc["particles"], "particles")
        check_keys(particles, PARTICLE_KEYS, "particles.")
        body = add_body(builder, particles, "particles.")
        add_body_effects(builder, doc, body, "")

    add_scene_effects(builder, doc)
    run = read_run(SceneBuilder.check_table(doc.get("run", {}), "run"), dt=Settings.dt, t_end=Settings.t_end)
    builder.settings = replace(Settings(), **canonical({**run, **overrides}))
    return builder.build(name, description)
