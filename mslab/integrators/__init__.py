"""Time integrators: explicit Runge-Kutta tableaux, symplectic and implicit methods."""

from mslab.integrators.base import COURSE_METHODS, Integrator, get_method, methods, register
from mslab.integrators.explicit import ExplicitRK
from mslab.integrators.implicit import ImplicitEuler, ImplicitEulerFixedPoint, ImplicitMidpoint
from mslab.integrators.symplectic import Leapfrog, SymplecticEuler, SymplecticEulerX, VelocityVerlet, Verlet

__all__ = ["COURSE_METHODS", "Integrator", "get_method", "methods", "register", "ExplicitRK",
           "ImplicitEuler", "ImplicitEulerFixedPoint", "ImplicitMidpoint", "Leapfrog",
           "SymplecticEuler", "SymplecticEulerX", "Verlet", "VelocityVerlet"]
