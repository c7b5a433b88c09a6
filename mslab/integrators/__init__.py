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

from mslab.integrators.base import COURSE_METHODS, FAMILIES, Integrator, get_method, methods, register
from mslab.integrators.runge_kutta import ExplicitRK, ImplicitRK
from mslab.integrators.splitting import Splitting
from mslab.integrators.two_step import Leapfrog, Verlet

_FRAMEWORK = {"base", "coefficients", "linear", "local_global", "local_step", "runge_kutta", "solvers",
              "splitting", "two_step"}

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name not in _FRAMEWORK and not _info.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_info.name}")

__all__ = ["COURSE_METHODS", "FAMILIES", "ExplicitRK", "ImplicitRK", "Integrator", "Leapfrog", "Splitting",
           "Verlet", "get_method", "methods", "register"]
