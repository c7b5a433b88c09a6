"""What ``mslab.derive`` reads from a method: its coefficients, chosen by what it carries.

A Runge-Kutta method (explicit or implicit) carries ``coefficients = {"A", "b", "c"}``, a
splitting ``coefficients = {"drift", "kick"}``, both exactly as the user gave them. The
two-step (Verlet) and staggered (leapfrog) adapters carry ``splitting``, the splitting
they equal, and ``family``. No method class is tested for: only these attributes.

A method that iterates towards another one's step (``converges_to``: the fast mass-spring
method minimises implicit Euler's objective) is read as that method. Any other integrator
(a user's own ``Integrator`` subclass) is analysed by a symbolic run of its own ``start``
and ``step``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mslab.integrators.base import get_method

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator


@dataclass(frozen=True)
class Reading:
    """A method as ``mslab.derive`` sees it.

    Attributes
    ----------
    kind : {"rk", "splitting", "run"}
        Butcher tableau, drift/kick splitting, or a symbolic run of ``start``/``step``.
    name : str
    A, b : tuple
        Tableau (``kind == "rk"``), coefficients as given.
    drift, kick : tuple
        Splitting coefficients (``kind == "splitting"``), as given.
    splitting : Reading or None
        For a run: the splitting the method equals, if it names one.
    two_step : bool
        For a run: the method is the two-step formula ``x_{n+1} = 2 x_n - x_{n-1} + h^2 a_n``.
    method : object
        The method object itself (what a run steps).
    """

    kind: str
    name: str
    A: tuple = ()
    b: tuple = ()
    drift: tuple = ()
    kick: tuple = ()
    splitting: Reading | None = None
    two_step: bool = False
    method: object = None

    def key(self) -> tuple:
        """Return a hashable key, equal for equal coefficients (a run is keyed by its object)."""
        if self.kind == "run":
            return ("run", self.name, id(self.method))
        return (self.kind, self.name, repr((self.A, self.b, self.drift, self.kick)))


def _rows(A: Sequence[Sequence]) -> tuple:
    return tuple(tuple(row) for row in A)


def read(method: str | Integrator) -> Reading:
    """Read a registry name or method object.

    Raises
    ------
    KeyError
        Unknown registry name (from ``mslab.get_method``).
    """
    m = get_method(method) if isinstance(method, str) else method
    name = str(getattr(m, "name", type(m).__name__))
    coefficients = getattr(m, "coefficients", None) or {}
    if "A" in coefficients:
        return Reading("rk", name, A=_rows(coefficients["A"]), b=tuple(coefficients["b"]), method=m)
    if "drift" in coefficients:
        return Reading("splitting", name, drift=tuple(coefficients["drift"]),
                       kick=tuple(coefficients["kick"]), method=m)
    limit = getattr(m, "converges_to", None)
    if limit is not None:  # an iteration that minimises another method's objective (local/global)
        return read(limit)
    family = getattr(m, "family", None)
    inner = getattr(m, "splitting", None)
    return Reading("run", name, splitting=read(inner) if inner is not None else None,
                   two_step=family == "two_step", method=m)
