"""The Integrator protocol and the registry of methods by name.

An integrator advances a :class:`~mslab.state.State` of the second-order system
``x' = v, v' = a(x, v)`` (lecture notes, eq. 3) by one fixed step ``dt``. It holds nothing about
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
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mslab.errors import broken_files, note_broken, warn_broken
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

    def evaluations_per_step(self, system: System) -> int:
        """Force evaluations one step of this method makes on ``system`` (cost: O(1)).

        Default :attr:`n_stages`; a method whose count depends on the forces (a splitting
        whose kicks step velocity-dependent forces with a Runge-Kutta method) says so.
        """
        return max(1, self.n_stages)

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
#: name -> (file that registered it, registered from ``__main__``: a script or notebook)
_ORIGIN: dict[str, tuple[str, bool]] = {}

#: the order check :func:`set_order_check` installs, and the methods registered before it was
_order_check: Callable[[Integrator], None] | None = None
_PENDING: list[tuple[Integrator, str, int]] = []

#: The package's own method modules. Their declared orders are held equal to the derived
#: ones by the tests (``tests/test_derive.py``) instead of at every import, which would load
#: sympy on ``import mslab``; every other registration derives its order when it is made.
BUILT_IN_MODULES = ("explicit_tableaux", "implicit_tableaux", "symplectic", "verlet_leapfrog",
                    "fast_mass_spring")


def register(method: Integrator) -> Integrator:
    """Add a method to the registry under ``method.name``, after checking what it is given.

    Checks, each refused with a ``ValueError`` of one line:

    * the name: letters, digits and ``_``, not taken by another file (a clash names both
      files; the same file, or a script or notebook registering again, replaces its own);
    * the coefficients: a Runge-Kutta tableau's ``c`` equals the row sums of ``A`` and its
      weights ``b`` sum to 1; a splitting's drifts and kicks each sum to 1 (consistency);
    * the order: derived from the coefficients with :func:`mslab.derive.order` (rooted
      trees, exact for exact coefficients) for a tableau or splitting registered from
      anywhere but the package's built-in modules; a declared order that differs is
      refused with both numbers, and ``order=0`` (not declared) takes the derived one
      (:func:`mslab.derive.declared.check_declared_order`, installed by
      :func:`set_order_check`).
    """
    if not method.name or not method.name.replace("_", "").isalnum():
        raise ValueError(f"a registered method needs a name of letters, digits and '_', got {method.name!r}")
    if method.family not in FAMILIES:
        raise ValueError(f"method {method.name!r}: unknown family {method.family!r}")
    frame = sys._getframe(1)
    origin = (frame.f_code.co_filename, frame.f_globals.get("__name__") == "__main__")
    _check_name(method.name, origin)
    _check_consistent(method)
    path = Path(origin[0])
    catalogue = Path(__file__).resolve().parent / "catalogue"
    built_in = path.stem in BUILT_IN_MODULES and path.resolve().parent == catalogue
    has_coefficients = bool({"A", "drift"} & set(method.coefficients))
    if has_coefficients and not built_in:
        if _order_check is not None:
            _order_check(method)
        else:  # imported before the check was installed: checked by set_order_check
            _PENDING.append((method, origin[0], frame.f_lineno))
    _REGISTRY[method.name] = method
    _ORIGIN[method.name] = origin
    return method


def _check_name(name: str, origin: tuple[str, bool]) -> None:
    if name not in _REGISTRY:
        return
    before = _ORIGIN.get(name, ("<unknown>", False))
    if before[0] == origin[0] or (before[1] and origin[1]):
        return
    raise ValueError(f"method name {name!r} of {origin[0]} is already registered by {before[0]}: choose "
                     f"another name (built-in and other files' methods are never replaced)")


def _close_to(value: float, target: float, scale: float) -> bool:
    return abs(value - target) <= 1e-12 * max(1.0, scale)


def _check_consistent(method: Integrator) -> None:
    """Refuse ``c`` that is not the row sums of ``A``, and weights that do not sum to 1."""
    given = method.coefficients
    name = method.name
    if "A" in given:
        A, b, c = (np.asarray(method.A), np.asarray(method.b), np.asarray(method.c))
        rows = A.sum(axis=1)
        for i in range(rows.size):
            if not _close_to(c[i], rows[i], float(np.abs(A[i]).sum())):
                raise ValueError(f"method {name!r}: c[{i}] = {c[i]:.17g} is not the row sum of A, "
                                 f"{rows[i]:.17g} (c_i = sum_j A_ij; leave c out to use the row sums)")
        pairs = (("b", b),)
    elif "drift" in given:
        pairs = (("drift", np.asarray(method.drift)), ("kick", np.asarray(method.kick)))
    else:
        return
    for key, w in pairs:
        if not _close_to(float(w.sum()), 1.0, float(np.abs(w).sum())):
            raise ValueError(f"method {name!r}: the weights {key} sum to {float(w.sum()):.17g}, not 1 "
                             f"(inconsistent: not even order 1)")


def set_order_check(check: Callable[[Integrator], None]) -> None:
    """Install the check of declared orders and run it on the methods registered before.

    The check derives the order from the coefficients (:mod:`mslab.derive`, an analysis layer
    above this one): the package's ``__init__`` installs it right after the method files
    were imported, so the files found then are checked here. A method it refuses is taken
    out with everything its file registered, and its file is reported in one line.
    """
    global _order_check
    _order_check = check
    pending = list(_PENDING)
    _PENDING.clear()
    for method, path, line in pending:
        if _REGISTRY.get(method.name) is not method:
            continue  # replaced or removed since
        try:
            check(method)
        except ValueError as err:
            for name in [n for n, (file, _) in _ORIGIN.items() if file == path]:
                _REGISTRY.pop(name, None)
                _ORIGIN.pop(name, None)
            note_broken(f"{path}:{line}: {err}")


def methods() -> list[str]:
    """Registry names: the course's methods first, in teaching order, then the others."""
    warn_broken()
    course = [m for m in COURSE_METHODS if m in _REGISTRY]
    return course + sorted(m for m in _REGISTRY if m not in COURSE_METHODS)


def get_method(name: str | Integrator) -> Integrator:
    """Return the registered integrator called ``name`` (``-`` and ``_`` are interchangeable).

    Raises ValueError naming the valid methods (and the closest one) otherwise.
    """
    if isinstance(name, Integrator):
        return name
    warn_broken()
    key = str(name).strip().lower().replace("-", "_")
    if key in _REGISTRY:
        return _REGISTRY[key]
    close = difflib.get_close_matches(key, list(_REGISTRY), n=4, cutoff=0.6)
    hint = f" (did you mean '{close[0]}'?)" if len(close) == 1 else \
        f" (close: {', '.join(sorted(close))})" if close else ""
    broken = [line for line in broken_files() if f"/{key}.py:" in line]
    skipped = f"; its file was skipped: {broken[0]}" if broken else ""
    raise ValueError(f"unknown method '{name}'{hint}{skipped}; valid methods: {', '.join(methods())}")
