"""Force terms ("effects") of a mass-spring system, one module each, found on import.

Every module of this package that registers an :class:`Effect` subclass (see
:mod:`mslab.effects.registry` and ``docs/extending.md``) is imported here, so the
``SceneBuilder``, the scene-file loader, the validator and the docs table know it.
"""

from mslab.effects.anchors import Anchors
from mslab.effects.base import BuildContext, Effect
from mslab.effects.colliders import PenaltyCollider, Plane, Sphere
from mslab.effects.damping import Damping
from mslab.effects.gravity import Gravity, down
from mslab.effects.registry import discover, effect_classes, get_effect, register
from mslab.effects.schema import Key
from mslab.effects.springs import Springs
from mslab.effects.wind import Wind

discover()

__all__ = ["Anchors", "BuildContext", "Damping", "Effect", "Gravity", "Key", "PenaltyCollider", "Plane",
           "Sphere", "Springs", "Wind", "discover", "down", "effect_classes", "get_effect", "register"]
