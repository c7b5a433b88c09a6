"""The Integrator protocol and the registry of methods by name.

An integrator advances a :class:`~mslab.state.State` of the second-order system
``x' = v, v' = a(x, v)`` (seed eq. 3) by one fixed step ``dt``. It holds nothing about
the scene: ``step(system, state, dt)`` returns a new State and mutates nothing it was
given. Multistep methods (Verlet, leapfrog) keep what they need between steps in
``State.memory``, created by ``start``.
"""

from __future__ import annotations

import difflib

from mslab.state import State

#: The integrators the course teaches, in teaching order.
COURSE_METHODS = ("euler", "symplectic_euler", "symplectic_euler_x", "heun", "midpoint", "rk4",
                  "verlet", "leapfrog", "implicit_euler", "implicit_euler_fp")


class Integrator:
    """Base class of every method.

    Attributes
    ----------
    name : str
        Registry name.
    order : int
        Global order p (local error O(h^(p+1))).
    explicit : bool
        No equation has to be solved per step.
    symplectic : bool
        Preserves the symplectic form (bounded energy error on Hamiltonian systems).
    n_stages : int
        Force evaluations per step (for implicit methods: per iteration).
    n_start : int
        Extra force evaluations made once by ``start``.
    """

    name: str = ""
    order: int = 0
    explicit: bool = True
    symplectic: bool = False
    n_stages: int = 1
    n_start: int = 0
    course: bool = False

    def start(self, system, state: State, dt: float) -> State:
        """Prepare a run (start-up step of a multistep method). Default: nothing."""
        return state

    def step(self, system, state: State, dt: float) -> State:
        raise NotImplementedError

    @property
    def implicit(self) -> bool:
        return not self.explicit

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}, order {self.order}>"


_REGISTRY: dict[str, Integrator] = {}


def register(method: Integrator) -> Integrator:
    """Add a method to the registry under ``method.name``."""
    _REGISTRY[method.name] = method
    return method


def methods() -> list[str]:
    """Registry names: the course's methods first, in teaching order, then the others."""
    course = [m for m in COURSE_METHODS if m in _REGISTRY]
    return course + sorted(m for m in _REGISTRY if m not in COURSE_METHODS)


def get_method(name: str | Integrator) -> Integrator:
    """The registered integrator called ``name`` (``-`` and ``_`` are interchangeable).

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
