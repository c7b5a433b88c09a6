"""The registry's check of a declared order: derived from the coefficients, or refused.

:func:`mslab.integrators.base.register` calls :func:`check_declared_order` (installed by the
package's ``__init__`` through :func:`~mslab.integrators.base.set_order_check`: the
registry sits below this analysis layer) for every tableau or splitting registered from
outside the package's built-in method modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mslab.derive.analysis import order

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator


def check_declared_order(method: Integrator) -> None:
    """Derive the order of a tableau or splitting; refuse a declared order that differs.

    ``method.order == 0`` means "not declared": it is set to the derived order. Otherwise
    the conditions are checked through ``declared + 1`` only (the cheapest check that tells
    both a lower and a higher order).

    Raises
    ------
    ValueError
        One line with both numbers (and, for a splitting of too low an order, a hint about
        the leading zero drift of a kick-first method).
    """
    declared = int(method.order)
    try:
        derived = order(method, max_order=declared if declared > 0 else 8)
    except ValueError as err:
        if "order >" not in str(err):
            raise ValueError(f"method {method.name!r}: {err}") from None
        derived = None
    if declared == 0 and derived is not None:
        method.order = derived
        return
    if derived == declared:
        return
    found = f"more than {declared}" if derived is None else str(derived)
    hint = ""
    if method.family == "splitting" and derived is not None and derived < declared:
        hint = " (a splitting steps drift first: to begin with a kick, begin drift with a 0)"
    raise ValueError(f"method {method.name!r} declares order {declared}, but its coefficients have order "
                     f"{found} (mslab.derive.order){hint}")
