"""Effect sections of a scene file, checked and built by the effect modules the registry lists.

Three forms, as each effect declares (:class:`~mslab.effects.base.Effect`):

* ``[gravity]`` — one table (``section``);
* ``[[colliders]]`` with ``type = "plane"`` — an array of tables, one effect each
  (``many``, ``kind``);
* ``[springs.<kind>]`` beside ``[particles]``, or ``[bodies.springs.<kind>]`` — tables of
  one body (``per_body``).

Every table goes to its effect's ``from_toml``, which checks it against the effect's key
schema and adds the effect through the ``SceneBuilder``.
"""

from __future__ import annotations

from collections.abc import Mapping

from mslab.effects import registry
from mslab.effects.schema import describe, string
from mslab.errors import SceneError
from mslab.scenes.bodies import Body
from mslab.scenes.builder import SceneBuilder


def scene_sections() -> list[str]:
    """Top-level sections of the effects that are not part of a body, in registry order."""
    return [name for name, classes in registry.sections().items() if not classes[0].per_body]


def body_sections() -> list[str]:
    """Sections of the effects that belong to a body (``springs``)."""
    return [name for name, classes in registry.sections().items() if classes[0].per_body]


def add_body_effects(builder: SceneBuilder, tables: Mapping, body: Body, prefix: str) -> None:
    """Return the per-body effect sections found in ``tables`` (``prefix``: ``""`` or ``bodies[1].``)."""
    for name in body_sections():
        if name in tables:
            cls = registry.sections()[name][0]
            cls.from_toml(builder, tables[name], f"{prefix}{name}.", body)


def add_scene_effects(builder: SceneBuilder, doc: Mapping) -> None:
    """Return the scene-level effect sections of a parsed file, in registry order."""
    for name, classes in registry.sections().items():
        if classes[0].per_body or name not in doc:
            continue
        raw = doc[name]
        if not classes[0].many:
            classes[0].from_toml(builder, SceneBuilder.check_table(raw, name), f"{name}.")
            continue
        what = name.rstrip("s") or name
        if not isinstance(raw, list):
            raise SceneError(name, f"must be an array of tables: write [[{name}]] once per {what}, "
                             f"got {describe(raw)}")
        kinds = {cls.kind: cls for cls in classes}
        for q, table in enumerate(raw):
            p = f"{name}[{q}]."
            table = SceneBuilder.check_table(table, p.rstrip("."))
            if "type" not in table:
                raise SceneError(f"{p}type", f"missing: {' or '.join(repr(k) for k in kinds)}")
            kind = string(table["type"], f"{p}type", tuple(kinds))
            kinds[kind].from_toml(builder, table, p)
