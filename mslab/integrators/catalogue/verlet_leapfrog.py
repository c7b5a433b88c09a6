"""The course's Verlet (two-step positions) and leapfrog (staggered velocities)."""

from mslab.integrators.base import register
from mslab.integrators.catalogue.symplectic import velocity_verlet
from mslab.integrators.families.two_step import Leapfrog, Verlet

verlet = register(Verlet("verlet", 2, velocity_verlet))
leapfrog = register(Leapfrog("leapfrog", 2, velocity_verlet))
