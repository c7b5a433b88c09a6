"""The Integrator protocol and the registry of methods by name.

An integrator advances a :class:`~mslab.state.State` of the second-order system
``x' = v, v' = a(x, v)`` (seed eq. 3) by one fixed step ``dt``. It holds nothing about
the scene: ``step(system, state, dt)`` returns a new State and mutates nothing it was
given. Methods with memory (velocity Verlet's reused acceleration, Verlet, leapfrog) keep
what they need between steps in ``State.memory``, created by ``start``.

Every method belongs to a *family* (``family``): a family is one class with one stepping
code path, and a method is an instance of it holding nothing but coefficients. Besides
stepping, a family answers for its methods what the analysis needs:

* ``stability_function(z)`` — ``R(z)`` on Dahlquist's ``y' = lam y`` (Runge-Kutta
  families), or None for methods without a scalar ``R``;
* ``oscillator_matrix(h_omega, h_gamma)`` — the one-step map on the damped oscillator
  ``x'' = -w^2 x - gamma x'`` from the coefficients;
* ``compiled`` — which compiled loop of :mod:`mslab.fast` steps it, and with what arrays.
"""

from __future__ import annotations

import difflib
from typing import TYPE_CHECKING

import numpy as np

from mslab.state import State

if TYPE_CHECKING:
    from mslab.system import System

#: The integrators the course teaches, in teaching order.
COURSE_METHODS = ("euler", "symplectic_euler", "symplectic_euler_x", "heun", "midpoint", "rk4",
                  "verlet", "leapfrog", "implicit_euler", "implicit_euler_fp")

#: The families, each one class in mslab/integrators/.
FAMILIES = ("explicit_rk", "implicit_rk", "splitting", "two_step", "staggered", "local_global")


class Integrator:
    """Base class of every method.

    Attributes
    ----------
    name : str
        Registry name.
    order : int
        Global order p (local error O(h^(p+1))).
    family : str
        One of :data:`FAMILIES`.
    explicit : bool
        No equation has to be solved per step.
    symplectic : bool
        Preserves the symplectic form (bounded energy error on Hamiltonian systems).
    a_stable : bool
        Stable for every ``z`` with ``Re z <= 0``: no step limit to predict.
    n_stages : int
        Force evaluations per step (for implicit methods: per iteration and stage).
    n_start : int
        Extra force evaluations made once by ``start``.
    coefficients : dict
        The coefficients as given (read by :mod:`mslab.derive`).
    """

    name: str = ""
    order: int = 0
    family: str = ""
    explicit: bool = True
    symplectic: bool = False
    a_stable: bool = False
    n_stages: int = 1
    n_start: int = 0
    coefficients: dict = {}

    def start(self, system: System, state: State, dt: float) -> State:
        """Prepare a run (start-up step of a method with memory). Default: nothing."""
        return state

    def step(self, system: System, state: State, dt: float) -> State:
        """One step of size ``dt``: a new State; ``state`` is not modified."""
        raise NotImplementedError

    def stability_function(self, z: np.ndarray) -> np.ndarray | None:
        """``R(z)`` for an array of complex ``z``; None when the method has no scalar R."""
        return None

    def oscillator_matrix(self, h_omega: np.ndarray, h_gamma: np.ndarray) -> np.ndarray:
        """One-step map ``(..., k, k)`` on ``x'' = -w^2 x - gamma x'`` (scaled state, dt = 1)."""
        raise NotImplementedError

    @property
    def compiled(self) -> tuple[str, tuple] | None:
        """``(loop name, coefficient arrays)`` for :mod:`mslab.fast`, or None (numpy only)."""
        return None

    @property
    def implicit(self) -> bool:
        """An equation is solved per step."""
        return not self.explicit

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}, order {self.order}>"


_REGISTRY: dict[str, Integrator] = {}


def register(method: Integrator) -> Integrator:
    """Add a method to the registry under ``method.name`` (replacing one of that name)."""
    if not method.name or not method.name.replace("_", "").isalnum():
        raise ValueError(f"a registered method needs a name of letters, digits and '_', got {method.name!r}")
    if method.family not in FAMILIES:
        raise ValueError(f"method {method.name!r}: unknown family {method.family!r}")
    _REGISTRY[method.name] = method
    return method


def methods() -> list[str]:
    """Registry names: the course's methods first, in teaching order, then the others."""
    course = [m for m in COURSE_METHODS if m in _REGISTRY]
    return course + sorted(m for m in _REGISTRY if m not in COURSE_METHODS)


def get_method(name: str | Integrator) -> Integrator:
    """Return the registered integrator called ``name`` (``-`` and ``_`` are interchangeable).

    Raises ValueError naming the valid methods (and the closest one) otherwise.
    """
    if isinstance(name, Integrator):
        return name
    key = str(name).strip().lower().replace("-", "_")
    if key in _REGISTRY:
        return _REGISTRY[key]
    close = difflib.get_close_matches(key, list(_REGISTRY), n=1)
    hint = f" (did you mean '{close[0]}'?)" if close else ""
    raise ValueError(f"unknown method '{name}'{hint}; valid methods: {', '.join(methods())}")
