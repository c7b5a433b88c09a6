"""Coefficients as the user gives them: exact where they are exact, floats for stepping.

A method is its coefficients. The stepping code and the stability analysis read float
arrays; :mod:`mslab.derive` reads the coefficients *as given* (``Fraction``, sympy
numbers and expressions, strings such as ``"19372/6561"``, ints or floats), so exact
ones stay exact there (and in :mod:`mslab.integrators.families.polynomials`, as ``Fraction``).
Both are made once here, when a method is created, and frozen.

Text is read by :func:`parse_text`, a small fixed grammar with bounded length, digits and
exponents (numbers, ``+ - * /``, parentheses, ``sqrt``): a coefficient string is data,
never handed to ``eval`` or ``sympy.sympify`` (which run Python) nor to ``Fraction``
unbounded (``Fraction("1e10000000")`` costs seconds).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from fractions import Fraction
from numbers import Number
from typing import Any

import numpy as np

#: longest coefficient text, most digits of one number, largest |decimal exponent|, deepest nesting
MAX_TEXT, MAX_DIGITS, MAX_EXPONENT, MAX_NESTING = 200, 60, 400, 32
#: largest numerator or denominator (bits) under a square root
MAX_ROOT_BITS = 512
_TOKEN = re.compile(r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<name>sqrt)|(?P<op>[-+*/()]))")
_NUMBER = re.compile(r"(?P<int>\d*)\.?(?P<frac>\d*)(?:[eE](?P<exp>[+-]?\d+))?")


def _tokens(text: str) -> list[str]:
    if not isinstance(text, str):
        raise TypeError(f"coefficient text must be a str, got {type(text).__name__}")
    if len(text) > MAX_TEXT:
        raise ValueError(f"coefficient text longer than {MAX_TEXT} characters")
    out, pos, end = [], 0, len(text.rstrip())
    while pos < end:
        m = _TOKEN.match(text, pos)
        if m is None:
            raise ValueError(f"coefficient {text!r} is not a number (only numbers, + - * /, "
                             f"parentheses and sqrt are read)")
        out.append(m.group(m.lastgroup))
        pos = m.end()
    if not out:
        raise ValueError("empty coefficient text")
    return out


def _number(token: str) -> Fraction:
    m = _NUMBER.fullmatch(token)
    digits = m.group("int") + m.group("frac")
    if len(digits.lstrip("0")) > MAX_DIGITS:
        raise ValueError(f"coefficient number {token[:40]!r}... has more than {MAX_DIGITS} digits")
    exp = m.group("exp") or "0"
    if len(exp.lstrip("+-").lstrip("0")) > 4 or abs(int(exp)) > MAX_EXPONENT:
        raise ValueError(f"coefficient number {token[:40]!r}: exponent beyond +-{MAX_EXPONENT}")
    shift = int(exp) - len(m.group("frac"))
    mantissa = int(digits or "0")
    return Fraction(mantissa * 10**shift) if shift >= 0 else Fraction(mantissa, 10**-shift)


class _Reader:
    """Recursive descent over the tokens: expr = term {+- term}, term = unary {*/ unary}."""

    def __init__(self, tokens: list[str]):
        self.tokens, self.pos, self.depth = tokens, 0, 0

    def peek(self) -> str | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def take(self, expected: str | None = None) -> str:
        tok = self.peek()
        if tok is None or (expected is not None and tok != expected):
            raise ValueError(f"coefficient text: expected {expected or 'more'}, got {tok!r}")
        self.pos += 1
        return tok

    def expr(self) -> Any:
        self.depth += 1
        if self.depth > MAX_NESTING:
            raise ValueError(f"coefficient text nested deeper than {MAX_NESTING}")
        value = self.term()
        while self.peek() in ("+", "-"):
            value = value + self.term() if self.take() == "+" else value - self.term()
        self.depth -= 1
        return value

    def term(self) -> Any:
        value = self.unary()
        while self.peek() in ("*", "/"):
            if self.take() == "*":
                value = value * self.unary()
            else:
                divisor = self.unary()
                if divisor == 0:
                    raise ValueError("coefficient text divides by zero")
                value = value / divisor
        return value

    def unary(self) -> Any:
        if self.peek() in ("+", "-"):
            sign = self.take()
            self.depth += 1
            if self.depth > MAX_NESTING:
                raise ValueError(f"coefficient text nested deeper than {MAX_NESTING}")
            value = self.unary()
            self.depth -= 1
            return -value if sign == "-" else value
        tok = self.take()
        if tok == "(":
            value = self.expr()
            self.take(")")
            return value
        if tok == "sqrt":
            self.take("(")
            value = self.expr()
            self.take(")")
            return _sqrt(value)
        if tok[0].isdigit() or tok[0] == ".":
            return _number(tok)
        raise ValueError(f"coefficient text: unexpected {tok!r}")


def _sqrt(value: Any) -> Any:
    import sympy

    r = sympy.Rational(value.numerator, value.denominator) if isinstance(value, Fraction) else value
    if r.is_Rational and max(abs(int(r.p)).bit_length(), int(r.q).bit_length()) > MAX_ROOT_BITS:
        raise ValueError(f"coefficient text: square root of a number beyond {MAX_ROOT_BITS} bits")
    if r.is_negative:
        raise ValueError("coefficient text: square root of a negative number")
    return sympy.sqrt(r)


def parse_text(text: str) -> Any:
    """Read a coefficient written as text: a ``Fraction``, or a sympy number when it has ``sqrt``.

    The grammar is fixed and bounded (:data:`MAX_TEXT` characters, :data:`MAX_DIGITS`
    digits per number, decimal exponents within :data:`MAX_EXPONENT`, nesting within
    :data:`MAX_NESTING`): numbers (``3``, ``-0.25``, ``1e-3``), ``+ - * /``, parentheses
    and ``sqrt(...)``, e.g. ``"19372/6561"``, ``"1 - sqrt(2)/2"``. Nothing is evaluated
    as code.

    Raises
    ------
    ValueError
        Any other text, or one beyond the bounds.
    """
    reader = _Reader(_tokens(text))
    value = reader.expr()
    if reader.peek() is not None:
        raise ValueError(f"coefficient text: unexpected {reader.peek()!r}")
    return value


def to_float(value: Any) -> float:
    """One coefficient as a float: numbers, ``Fraction``, sympy numbers, strings like ``"1/6"``."""
    if isinstance(value, str):
        try:
            return float(parse_text(value))
        except (OverflowError, TypeError):
            raise ValueError(f"coefficient {value[:40]!r} is not a real number in the float range") from None
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
        parsed = parse_text(value)
        if isinstance(parsed, Fraction):
            return parsed, True
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
