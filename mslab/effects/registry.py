"""The effect registry: every module of the ``mslab.effects`` package is found on import.

A module that defines an effect decorates its class with :func:`register`; the package
imports each of its modules (:func:`discover`: once per process, again when the package's
``__path__`` changes or a name is not found, so a module added later is picked up), and the
``SceneBuilder``, the scene-file loader and validator, and the scene-format table of
``docs/scenes.md`` iterate :func:`effect_classes`.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys
from collections.abc import Callable

from mslab.effects.base import Effect
from mslab.errors import failure_line, note_broken, warn_broken

#: infrastructure modules of the package that define no effect
_INFRASTRUCTURE = {"base", "registry", "schema", "docs"}

_registry: dict[str, type[Effect]] = {}
_imported: set[str] = set()
_listeners: list[Callable[[type[Effect]], None]] = []
_scanned: list[str] | None = None  # the package's __path__ at the last scan of its folders


def register(cls: type[Effect]) -> type[Effect]:
    """Class decorator: add an effect class to the registry (by its ``name``)."""
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise TypeError(f"register() takes an Effect subclass, got {cls!r}")
    if not cls.name or cls.name == Effect.name:
        raise ValueError(f"{cls.__name__}: set the class attribute 'name'")
    old = _registry.get(cls.name)
    if old is not None and old.__module__ != cls.__module__:
        raise ValueError(f"effect name {cls.name!r} of {_file(cls)} is already registered by {_file(old)}: "
                         f"choose another name (built-in and other files' effects are never replaced)")
    for method in cls.builder_methods:
        if not callable(getattr(cls, method, None)):
            raise ValueError(f"{cls.__name__}: builder method '{method}' is not defined on the class")
        other = builder_method(method, rescan=False)
        if other is not None and other[0].name != cls.name:
            raise ValueError(f"{cls.__name__}: builder method '{method}' is already provided by "
                             f"{other[0].__name__}")
    _registry[cls.name] = cls
    for listener in _listeners:
        listener(cls)
    return cls


def _file(cls: type) -> str:
    return str(getattr(sys.modules.get(cls.__module__), "__file__", None) or cls.__module__)


def on_register(listener: Callable[[type[Effect]], None]) -> None:
    """Call ``listener(cls)`` for every effect class registered so far and every one registered later.

    How a layer above (the ``SceneBuilder``) learns of an effect without the effect importing it.
    """
    _listeners.append(listener)
    for cls in list(_registry.values()):
        listener(cls)


def discover() -> None:
    """Import every module of the ``mslab.effects`` package not imported yet.

    Modules on any folder of the package's ``__path__`` count, so a test (or a course
    installation) may add a folder to ``mslab.effects.__path__``. A module that fails to
    import is skipped with one line ``FILE:LINE: reason`` (:func:`mslab.errors.broken_files`,
    reported by the next lookup); the other effects keep working.
    """
    global _scanned
    import mslab.effects as package

    _scanned = list(package.__path__)
    for info in pkgutil.iter_modules(package.__path__):
        name = info.name
        if name in _INFRASTRUCTURE or name.startswith("_") or name in _imported:
            continue
        _imported.add(name)
        before = set(_registry)
        try:
            importlib.import_module(f"mslab.effects.{name}")
        except Exception as err:  # noqa: BLE001 - a broken effect file is skipped, the others work
            sys.modules.pop(f"mslab.effects.{name}", None)
            for added in set(_registry) - before:
                del _registry[added]
            path = os.path.join(getattr(info.module_finder, "path", ""), f"{name}.py")
            note_broken(failure_line(err, path))


def _discovered() -> None:
    """:func:`discover` unless the package's folders were scanned already (the disk is read once)."""
    import mslab.effects as package

    if _scanned != list(package.__path__):
        discover()


def effect_classes() -> list[type[Effect]]:
    """Return the registered effect classes in System order (``order``, then registration order)."""
    _discovered()
    warn_broken()
    return sorted(_registry.values(), key=lambda cls: cls.order)


def get_effect(name: str) -> type[Effect]:
    """Return the registered effect class called ``name`` (KeyError when unknown, after a new scan)."""
    _discovered()
    if name not in _registry:
        discover()
    warn_broken()
    return _registry[name]


def sections() -> dict[str, list[type[Effect]]]:
    """TOML section name -> the effects read from it (several for a ``[[...]]`` section with ``type``)."""
    out: dict[str, list[type[Effect]]] = {}
    for cls in effect_classes():
        if cls.section is not None:
            out.setdefault(cls.section, []).append(cls)
    return out


def builder_method(name: str, rescan: bool = True) -> tuple[type[Effect], Callable] | None:
    """``(effect class, function)`` of the ``SceneBuilder`` method ``name``, or None."""
    if rescan:
        _discovered()
    for cls in _registry.values():
        if name in cls.builder_methods:
            return cls, getattr(cls, name)
    return None


def builder_method_names() -> list[str]:
    """Every ``SceneBuilder`` method the registered effects provide."""
    return [m for cls in effect_classes() for m in cls.builder_methods]
