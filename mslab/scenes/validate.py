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

import numpy as np

from mslab.checks import shown
from mslab.effects.schema import check_keys, integer, string
from mslab.errors import SceneError
from mslab.files import name_problem
from mslab.scene import Scene, Settings
from mslab.scenes.bodies import PARTICLE_KEYS, add_body
from mslab.scenes.builder import SceneBuilder
from mslab.scenes.generators import GENERATORS, generator_shape
from mslab.scenes.sections import add_body_effects, add_scene_effects, body_sections, scene_sections
from mslab.scenes.settings import canonical, read_run

#: keys of ``[scene]``
SCENE_KEYS = ("name", "description", "dim")

#: largest magnitude of a number in a scene file: a run squares and multiplies them (``k d^2 / 2``,
#: ``k / m`` in the step-limit analysis), and 1e150 squared is still a double; SI scenes stay far below
MAX_MAGNITUDE = 1e150


def sections() -> tuple[str, ...]:
    """Every valid top-level section of a scene file."""
    return ("scene", "particles", *body_sections(), "bodies", *scene_sections(), "run")


def scene_from_doc(doc: Mapping, source: str | None = None, default_name: str = "scene",
                   overrides: Mapping | None = None, max_bytes: int | None = None) -> Scene:
    """Check a parsed scene file and build it; ``overrides`` replace ``[run]`` values (checked by the caller).

    Before anything is built: every number is finite and within :data:`MAX_MAGNITUDE`, and the
    positions and velocities of the particles the generators would make (``16 dim`` bytes
    each, the least a scene holds) fit in ``max_bytes`` (default: the machine's memory).
    After building: the initial forces and energy are finite.

    Raises
    ------
    SceneError
        The first problem found, naming the file (``source``) and the key.
    """
    try:
        _check_magnitudes(doc, "")
        _check_size(doc, max_bytes)
        scene = _build(doc, default_name, overrides or {})
        _check_initial_state(scene)
        return scene
    except SceneError as err:
        if err.source is not None:
            raise
        raise SceneError(err.key, err.reason, source) from None


def _check_magnitudes(value: object, key: str) -> None:
    """Refuse a number beyond :data:`MAX_MAGNITUDE`, naming its key (``particles.positions[1][0]``).

    Non-finite numbers are left to the keys' own checks, which say "must be finite".
    """
    if isinstance(value, Mapping):
        for k, v in value.items():
            _check_magnitudes(v, f"{key}.{k}" if key else str(k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _check_magnitudes(v, f"{key}[{i}]")
    elif isinstance(value, int | float) and not isinstance(value, bool) and abs(value) > MAX_MAGNITUDE:
        if isinstance(value, float) and not np.isfinite(value):
            return
        digits = len(str(abs(value))) if isinstance(value, int) else 0
        text = f"an integer of {digits} digits" if digits > 15 else f"{value:.3g}"
        raise SceneError(key, f"{text} is beyond +-{MAX_MAGNITUDE:.0e}: a run squares such numbers "
                         f"(energies k d^2 / 2, k / m), which overflows double precision")


def _bodies(doc: Mapping) -> list[tuple[str, Mapping]]:
    if isinstance(doc.get("bodies"), list):
        return [(f"bodies[{b}].", t) for b, t in enumerate(doc["bodies"]) if isinstance(t, Mapping)]
    return [("particles.", doc["particles"])] if isinstance(doc.get("particles"), Mapping) else []


def _check_size(doc: Mapping, max_bytes: int | None) -> None:
    """Refuse a scene whose generators would make more particles than memory holds (before making them)."""
    import os

    if max_bytes is None:
        try:
            max_bytes = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            return
    scene = doc.get("scene", {})
    dim = scene.get("dim", 2) if isinstance(scene, Mapping) else 2
    if isinstance(dim, bool) or dim not in (1, 2, 3):
        return  # a wrong dim (dim = "2") is named while building
    total, biggest = 0, ("particles.", 0)
    for prefix, table in _bodies(doc):
        generator = table.get("generator")
        if generator not in GENERATORS:
            continue  # an explicit list is already in memory; other mistakes are named while building
        n = int(np.prod(generator_shape(generator, table, prefix, dim)["shape"], dtype=object))
        total += n
        biggest = max(biggest, (prefix, n), key=lambda item: item[1])
    need = total * 16 * dim  # x and v: the least a scene holds
    if need > max_bytes:
        raise SceneError(f"{biggest[0]}generator", f"{_big(total)} particles would need at least "
                         f"{_big(need // 2**30)} GB (their positions and velocities alone), more than the "
                         f"{max_bytes / 2**30:.3g} GB allowed (the memory budget); use fewer particles")


def _big(n: int) -> str:
    return f"{n:.3g}" if n < 10**300 else f"10^{len(str(n)) - 1}"


def _check_initial_state(scene: Scene) -> None:
    """Refuse a scene whose initial forces or energies overflow (values that each fit, but not together)."""
    system, state = scene.system, scene.state0
    with np.errstate(all="ignore"):
        force = system.force(state.x, state.v)
        energy = system.kinetic_energy(state.v) + system.potential_energy(state.x)
    if not (np.all(np.isfinite(force)) and np.isfinite(energy)):
        what = "forces" if not np.all(np.isfinite(force)) else "energy"
        raise SceneError("scene", f"the initial {what} overflow double precision (inf or nan): positions, "
                         f"masses, stiffnesses or velocities too large together")


def _build(doc: Mapping, default_name: str, overrides: Mapping) -> Scene:
    check_keys(doc, sections(), "", "section")
    scene = SceneBuilder.check_table(doc.get("scene", {}), "scene")
    check_keys(scene, SCENE_KEYS, "scene.")
    name = string(scene.get("name", default_name), "scene.name")
    problem = name_problem(name)  # the rule `mslab run` names its output files by
    if problem:
        given = "" if "name" in scene else " (taken from the file's name; set [scene] name)"
        raise SceneError("scene.name", f"{shown(name)} {problem}{given}")
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
