"""Coefficients as the user gives them: exact where they are exact, floats for stepping.

A method is its coefficients. The stepping code and the stability analysis read float
arrays; :mod:`mslab.derive` reads the coefficients *as given* (``Fraction``, sympy
numbers and expressions, strings such as ``"19372/6561"``, ints or floats), so exact
ones stay exact there (and in :mod:`mslab.integrators.families.polynomials`, as ``Fraction``).
Both are made once here, when a method is created, and frozen.
"""

from __future__ import annotations

from collections.abc import Iterable
from fractions import Fraction
from numbers import Number
from typing import Any

import numpy as np


def to_float(value: Any) -> float:
    """One coefficient as a float: numbers, ``Fraction``, sympy numbers, strings like ``"1/6"``."""
    if isinstance(value, str):
        text = value.strip()
        try:
            return float(Fraction(text))
        except (ValueError, ZeroDivisionError):
            import sympy  # an expression such as "1/sqrt(2)"

            return float(sympy.sympify(text, rational=True))
    if isinstance(value, Number | np.number):
        return float(value)
    return float(value)  # sympy expressions define __float__


def as_fraction(value: Any) -> tuple[Fraction, bool]:
    """Return a coefficient as a Fraction, and whether that is its exact value (not a float's)."""
    if isinstance(value, bool):
        raise ValueError(f"coefficient {value!r} is a bool, not a number")
    if isinstance(value, int | Fraction):
        return Fraction(value), True
    if getattr(value, "is_Rational", False):  # a sympy Rational or Integer
        return Fraction(int(value.p), int(value.q)), True
    if isinstance(value, str):
        try:
            return Fraction(value.strip()), True
        except (ValueError, ZeroDivisionError):
            return Fraction(to_float(value)), False
    return Fraction(float(value)), False


def as_given(values: Any) -> tuple:
    """Nested tuples of the coefficients exactly as given (numpy scalars become Python ones)."""
    if isinstance(values, str) or not np.iterable(values):
        return values.item() if isinstance(values, np.generic) else values
    return tuple(as_given(v) for v in values)


def frozen(values: Iterable[Any], ndim: int) -> np.ndarray:
    """Return a read-only float array of the coefficients (ValueError on a wrong shape)."""
    arr = np.array([[to_float(v) for v in row] for row in values] if ndim == 2
                   else [to_float(v) for v in values], dtype=float)
    if arr.ndim != ndim:
        raise ValueError(f"coefficients must be a {ndim}-d array, got shape {arr.shape}")
    arr.flags.writeable = False  # the coefficients that step are the ones analysed
    return arr
