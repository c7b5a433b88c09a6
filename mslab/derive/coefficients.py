"""Coefficients as the user gave them: exact stay exact, floats stay floats.

A method's coefficients may be ints, floats, ``fractions.Fraction``, sympy numbers
(rational or irrational, e.g. ``1/sqrt(2)``) or strings (``"19372/6561"``, ``"0.25"``,
``"1 - sqrt(2)/2"``, read by the bounded grammar of
:func:`~mslab.integrators.families.coefficients.parse_text`, never evaluated as code).
:func:`exact` reads one into a sympy number (``None`` for a float);
:class:`Arithmetic` evaluates order conditions on a whole set of them, exactly (in the
smallest sympy domain that holds them all: the rationals, an algebraic number field such as
``QQ<sqrt(2)>``, or a polynomial ring for transcendental numbers) or, as soon as one is a
float, in floating point with a round-off bound per condition.
"""

from __future__ import annotations

from collections.abc import Iterable
from fractions import Fraction
from numbers import Integral, Real
from typing import Any

import numpy as np
import sympy as sp
from sympy.polys.constructor import construct_domain

from mslab.integrators.families.coefficients import parse_text

_EPS = float(np.finfo(float).eps)


def exact(value: Any) -> sp.Expr | None:
    """Return the exact sympy number a coefficient stands for, or ``None`` for a float.

    Raises
    ------
    ValueError
        A string that is not a number, or an expression with symbols.
    """
    if isinstance(value, bool):
        raise ValueError(f"coefficient {value!r} is a bool, not a number")
    if isinstance(value, Fraction):
        return sp.Rational(value.numerator, value.denominator)
    if isinstance(value, Integral):
        return sp.Integer(int(value))
    if isinstance(value, sp.Float):
        return None
    if isinstance(value, sp.Basic):
        expr = value
    elif isinstance(value, str):
        parsed = parse_text(value)  # a bounded grammar: the text is never evaluated as code
        if isinstance(parsed, Fraction):
            return sp.Rational(parsed.numerator, parsed.denominator)
        expr = parsed
    elif isinstance(value, Real):
        return None
    else:
        raise ValueError(f"coefficient {value!r} of type {type(value).__name__} is not a number")
    if not isinstance(expr, sp.Expr) or expr.free_symbols or not expr.is_number:
        raise ValueError(f"coefficient {value!r} is not a number")
    if expr.atoms(sp.Float):
        return None
    if not expr.is_real:
        raise ValueError(f"coefficient {value!r} is not real")
    return expr


def display(value: Any) -> sp.Expr:
    """Return a coefficient for printed series: exact if given exactly, else the float.

    A float becomes a fraction only when that fraction rounds to exactly this float
    (``0.5`` -> ``1/2``, ``1/6`` -> ``1/6``); any other float stays a sympy ``Float``.
    """
    e = exact(value)
    if e is not None:
        return e
    f = float(value)
    frac = Fraction(f).limit_denominator(10**6)
    if float(frac) == f:
        return sp.Rational(frac.numerator, frac.denominator)
    return sp.Float(f)


class Arithmetic:
    """Evaluate polynomial order conditions on one set of coefficients.

    Parameters
    ----------
    values : iterable
        Every coefficient of the method (they share one domain).

    Attributes
    ----------
    is_exact : bool
        ``True`` when no coefficient is a float.
    """

    def __init__(self, values: Iterable[Any]) -> None:
        values = list(values)
        parsed = [exact(v) for v in values]
        self.is_exact = all(p is not None for p in parsed)
        if self.is_exact:
            domain, elements = construct_domain(parsed, extension=True, field=True)
            self.domain = domain
            self._converted = elements
            self.zero, self.one = domain.zero, domain.one
        else:
            self.domain = None
            self._converted = [float(v) if p is None else float(sp.N(p, 20))
                               for p, v in zip(parsed, values, strict=True)]
            self.zero, self.one = 0.0, 1.0

    def elements(self) -> list:
        """All coefficients, converted, in the order given to the constructor."""
        return list(self._converted)

    def rational(self, num: int, den: int) -> Any:
        """Return the number ``num/den`` in this arithmetic."""
        if self.is_exact:
            return self.domain.from_sympy(sp.Rational(num, den))
        return num / den

    def satisfied(self, value: Any, target: Any, scale: float, n_ops: int) -> bool:
        """Tell whether a condition ``value = target`` holds.

        Exactly, when the coefficients are exact. For floats: ``|value - target|`` within
        the round-off bound ``2 n_ops eps (scale + |target|)``, where ``scale`` is the sum of
        the absolute values of the terms that make up ``value`` and ``n_ops`` bounds the
        number of roundings along one term (coefficients given to full double precision).
        """
        if self.is_exact:
            return value - target == self.zero
        return abs(value - target) <= 2.0 * n_ops * _EPS * (scale + abs(target))
