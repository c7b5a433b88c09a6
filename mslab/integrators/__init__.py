"""Time integrators: three families of coefficients and the adapters of the course.

* :class:`ExplicitRK`, :class:`ImplicitRK` — Butcher tableaux (``runge_kutta.py``),
  the implicit ones solved by Newton or fixed-point iteration (``solvers.py``);
* :class:`Splitting` — drift/kick coefficients (``splitting.py``);
* :class:`Verlet`, :class:`Leapfrog` — the course's two-step and staggered forms of a
  splitting (``two_step.py``).

Every other module of this package defines methods (instances holding coefficients) and
registers them; all of them are imported here, so a new file with a ``register(...)`` call
is picked up with no other edit.
"""

import importlib
import pkgutil
import sys

from mslab.integrators.base import COURSE_METHODS, FAMILIES, Integrator, get_method, methods, register
from mslab.integrators.runge_kutta import ExplicitRK, ImplicitRK
from mslab.integrators.splitting import Splitting
from mslab.integrators.two_step import Leapfrog, Verlet

#: modules of the package that define no method: families, Newton and linear algebra
#: (``tests/test_architecture.py`` checks that every other module registers methods)
_FRAMEWORK = {"base", "coefficients", "linear", "local_global", "local_step", "newton_matrix", "pcg",
              "runge_kutta", "solvers", "splitting", "two_step"}


def discover() -> list[str]:
    """Import every method module in this package's folders not imported yet; return their names.

    Runs once on import; call it again after adding a folder to ``__path__`` or a file to
    the package at run time (the tests of ``docs/extending.md`` do).
    """
    found = []
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        name = f"{__name__}.{info.name}"
        if info.name in _FRAMEWORK or info.name.startswith("_") or name in sys.modules:
            continue
        importlib.import_module(name)
        found.append(info.name)
    return found


discover()

__all__ = ["COURSE_METHODS", "FAMILIES", "ExplicitRK", "ImplicitRK", "Integrator", "Leapfrog", "Splitting",
           "Verlet", "discover", "get_method", "methods", "register"]
