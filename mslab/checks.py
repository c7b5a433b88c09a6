"""The one argument-checking layer of the public API: exact types, ranges, one error naming the argument.

Bools are not numbers, strings are not numbers, a float is not a count: a wrong type raises
``TypeError``, a value out of range ``ValueError``, each naming the argument. A leaf module
(numpy only), used by the stepping session, :func:`mslab.simulate` and the step arithmetic.
"""

from __future__ import annotations

import numbers
import operator

import numpy as np


def shown(value: object) -> str:
    """Return ``repr(value)`` cut to 60 characters (a hostile 5,000-character string stays one line)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def whole(name: str, value: object, minimum: int = 0) -> int:
    """Return ``value`` as an int: an int (or numpy integer, not a bool) ``>= minimum``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be a whole number (int), got {type(value).__name__} {shown(value)}")
    count = operator.index(value)
    if count < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {count}")
    return count


def real(name: str, value: object, *, positive: bool = False, minimum: float | None = None,
         allow_inf: bool = False) -> float:
    """Return ``value`` as a float: a real number (not a bool or a string), not NaN, in range.

    ``positive``: ``> 0``; ``minimum``: ``>= minimum``; ``allow_inf``: ``+inf`` accepted.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {type(value).__name__} {shown(value)}")
    try:
        number = float(value)
    except OverflowError:  # an int beyond any float (10**400)
        raise ValueError(f"{name} must be a finite number, got an int of {len(str(value))} digits") from None
    if np.isnan(number) or (np.isinf(number) and not (allow_inf and number > 0)):
        raise ValueError(f"{name} must be a finite number, got {shown(value)}")
    if positive and not number > 0:
        raise ValueError(f"{name} must be > 0, got {shown(value)}")
    if minimum is not None and number < minimum:
        raise ValueError(f"{name} must be >= {minimum:g}, got {shown(value)}")
    return number


def flag(name: str, value: object) -> bool:
    """Return ``value`` when it is a bool (or numpy bool); TypeError otherwise."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {type(value).__name__} {shown(value)}")
    return bool(value)
