"""Time integrators, in three folders that say what they hold.

* ``families/`` — one class per family, one stepping code path each: :class:`ExplicitRK`,
  :class:`ImplicitRK` (Butcher tableaux, ``runge_kutta.py``), :class:`Splitting` (drift/kick
  coefficients, ``splitting.py``), :class:`Verlet`, :class:`Leapfrog` (the course's two-step
  and staggered forms of a splitting, ``two_step.py``), the local/global iteration;
* ``catalogue/`` — the built-in methods: modules that hold coefficients and register them;
* ``newton/`` — Newton and fixed-point iteration for the implicit stages, and the linear
  algebra of Newton's systems.

``base.py`` holds the :class:`Integrator` protocol and the registry. Every module of
``catalogue/`` and every module saved next to this file (a user's own method,
``docs/extending.md``) is imported here, so a new file with a ``register(...)`` call is
picked up with no other edit. The modules of the families and of ``newton/`` stay reachable
by their short names (``from mslab.integrators import linear, solvers``), loaded on first use.
"""

import importlib
import os
import pkgutil
import sys

from mslab.errors import failure_line, note_broken
from mslab.integrators import base
from mslab.integrators.base import COURSE_METHODS, FAMILIES, Integrator, get_method, methods, register
from mslab.integrators.families.runge_kutta import ExplicitRK, ImplicitRK
from mslab.integrators.families.splitting import Splitting
from mslab.integrators.families.two_step import Leapfrog, Verlet

#: modules next to this file that define no method (``tests/test_architecture.py`` checks that
#: every module of ``catalogue/`` and every other module here registers methods)
_FRAMEWORK = {"base"}

#: the modules of the families and of newton/ by their short names (``from mslab.integrators import
#: solvers``), imported on first use: ``import mslab`` loads no linear algebra
_FOLDER_OF = {"coefficients": "families", "polynomials": "families", "runge_kutta": "families",
              "splitting": "families", "two_step": "families", "local_global": "families",
              "local_step": "families", "local_global_loop": "families", "linear": "newton",
              "newton_matrix": "newton", "pcg": "newton", "factor": "newton", "coupled": "newton",
              "solvers": "newton", "tree_solve": "newton", "tree_kernels": "newton",
              "damped": "newton", "mixed": "newton", "mixed_symbolic": "newton", "mixed_kernels": "newton"}


def discover() -> list[str]:
    """Import every method module in this package's folders not imported yet; return their names.

    Runs once on import; call it again after adding a folder to ``__path__`` or a file to
    the package at run time (the tests of ``docs/extending.md`` do). A file that fails (a
    syntax error, a NameError, a registration refused) is skipped with what it registered:
    one line ``FILE:LINE: reason`` is kept (:func:`mslab.errors.broken_files`) and reported
    by the next lookup of a method; the other methods keep working.
    """
    found = []
    catalogue = importlib.import_module(f"{__name__}.catalogue")
    for package in (catalogue, sys.modules[__name__]):
        for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
            name = f"{package.__name__}.{info.name}"
            if (info.ispkg or info.name in _FRAMEWORK or info.name.startswith("_") or name in sys.modules
                    or name in _FAILED):
                continue
            if _import_method_module(name, os.path.join(getattr(info.module_finder, "path", ""),
                                                        f"{info.name}.py")):
                found.append(info.name)
    return found


def _import_method_module(name: str, path: str) -> bool:
    """Import one method module; on any error forget what it registered, note one line, return False."""
    before = set(base._REGISTRY)
    try:
        importlib.import_module(name)
    except Exception as err:  # noqa: BLE001 - any error in a user's file: skip the file
        sys.modules.pop(name, None)
        for added in set(base._REGISTRY) - before:
            del base._REGISTRY[added]
        _FAILED.add(name)
        note_broken(failure_line(err, path))
        return False
    return True


def __getattr__(name: str):
    """Return a module of the families or of newton/ by its short name, imported on first use."""
    if name in _FOLDER_OF:
        return importlib.import_module(f"{__name__}.{_FOLDER_OF[name]}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


_FAILED: set[str] = set()


discover()

__all__ = ["COURSE_METHODS", "FAMILIES", "ExplicitRK", "ImplicitRK", "Integrator", "Leapfrog", "Splitting",
           "Verlet", "discover", "get_method", "methods", "register"]
