"""Force terms ("effects") of a mass-spring system, one module each."""

from mslab.effects.base import Effect
from mslab.effects.colliders import PenaltyCollider, Plane, Sphere
from mslab.effects.damping import Damping
from mslab.effects.gravity import Gravity
from mslab.effects.springs import Springs

__all__ = ["Effect", "Gravity", "Springs", "Damping", "PenaltyCollider", "Plane", "Sphere"]
