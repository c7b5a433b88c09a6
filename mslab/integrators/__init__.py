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
import os
import pkgutil
import sys

from mslab.errors import failure_line, note_broken
from mslab.integrators import base
from mslab.integrators.base import COURSE_METHODS, FAMILIES, Integrator, get_method, methods, register
from mslab.integrators.runge_kutta import ExplicitRK, ImplicitRK
from mslab.integrators.splitting import Splitting
from mslab.integrators.two_step import Leapfrog, Verlet

#: modules of the package that define no method: families, Newton and linear algebra
#: (``tests/test_architecture.py`` checks that every other module registers methods)
_FRAMEWORK = {"base", "coefficients", "linear", "local_global", "local_step", "newton_matrix", "pcg",
              "polynomials", "runge_kutta", "solvers", "splitting", "two_step"}


def discover() -> list[str]:
    """Import every method module in this package's folders not imported yet; return their names.

    Runs once on import; call it again after adding a folder to ``__path__`` or a file to
    the package at run time (the tests of ``docs/extending.md`` do). A file that fails (a
    syntax error, a NameError, a registration refused) is skipped with what it registered:
    one line ``FILE:LINE: reason`` is kept (:func:`mslab.errors.broken_files`) and reported
    by the next lookup of a method; the other methods keep working.
    """
    found = []
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        name = f"{__name__}.{info.name}"
        if info.name in _FRAMEWORK or info.name.startswith("_") or name in sys.modules or name in _FAILED:
            continue
        before = set(base._REGISTRY)
        try:
            importlib.import_module(name)
        except Exception as err:  # noqa: BLE001 - any error in a user's file: skip the file
            sys.modules.pop(name, None)
            for added in set(base._REGISTRY) - before:
                del base._REGISTRY[added]
            _FAILED.add(name)
            path = os.path.join(getattr(info.module_finder, "path", ""), f"{info.name}.py")
            note_broken(failure_line(err, path))
            continue
        found.append(info.name)
    return found


_FAILED: set[str] = set()


discover()

__all__ = ["COURSE_METHODS", "FAMILIES", "ExplicitRK", "ImplicitRK", "Integrator", "Leapfrog", "Splitting",
           "Verlet", "discover", "get_method", "methods", "register"]
