"""The stability function of a Butcher tableau: one definition, over any number type.

On Dahlquist's ``y' = lam y`` a Runge-Kutta method maps ``y_n`` to ``R(z) y_n``, ``z = lam h``,
with (lecture notes, eq. 29)::

    R(z) = N(z) / D(z),   N(z) = det(I - zA + z 1 b^T),   D(z) = det(I - zA).

:func:`stability_polynomials` computes the coefficients of ``N`` and ``D`` in the number type
of ``A`` and ``b``: ``fractions.Fraction`` (exact), sympy numbers (:mod:`mslab.derive`, exact
with irrational coefficients too), or floats. Every user of ``R`` reads it from there: the
family's ``stability_function(z)`` (floats rounded from the exact polynomials of
:func:`exact_polynomials`, cached per tableau), the stability limits of
:mod:`mslab.stability` (exact) and :func:`mslab.derive.stability_function` (sympy).
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction
from typing import Any, NamedTuple

import numpy as np

from mslab.integrators.families.coefficients import as_fraction


def stability_polynomials(A: Sequence[Sequence[Any]], b: Sequence[Any]) -> tuple[list, list]:
    """Return the coefficients (ascending) of ``N(z) = det(I - zA + z 1 b^T)`` and ``D(z) = det(I - zA)``.

    Computed in the number type of ``A`` and ``b`` (any commutative field that divides by
    integers: ``Fraction``, sympy numbers, floats), with no test for zero. An explicit tableau
    (``A`` strictly lower triangular) has ``D = 1`` and ``N_k = b^T A^(k-1) 1`` (the Neumann
    series of ``(I - zA)^-1``), ``k = 0..s``; otherwise ``det(I - zM) = sum_k c_k z^k`` with
    ``c_k`` the characteristic polynomial's coefficients of ``M = A - 1 b^T`` and ``M = A``,
    by the Faddeev-LeVerrier recurrence.
    """
    s = len(b)
    zero = b[0] - b[0]
    one = zero + 1
    if all(A[i][j] == 0 for i in range(s) for j in range(i, s)):  # explicit: D = 1
        N, w = [one], [one] * s
        for _ in range(s):
            N.append(sum((bi * wi for bi, wi in zip(b, w, strict=True)), zero))
            w = [sum((A[i][j] * w[j] for j in range(s)), zero) for i in range(s)]
        return N, [one]
    shifted = [[A[i][j] - b[j] for j in range(s)] for i in range(s)]
    return _det_one_minus_z(shifted, zero, one), _det_one_minus_z(A, zero, one)


def _det_one_minus_z(M: Sequence[Sequence[Any]], zero: Any, one: Any) -> list:
    """Coefficients (ascending) of ``det(I - zM) = sum_k c_k z^k`` (Faddeev-LeVerrier)."""
    s = len(M)
    coef = [one]
    P = [[zero] * s for _ in range(s)]  # P_k = M P_(k-1) + c_(k-1) I, c_k = -tr(M P_k) / k
    for k in range(1, s + 1):
        P = [[sum((M[i][m] * P[m][j] for m in range(s)), zero) + (coef[-1] if i == j else zero)
              for j in range(s)] for i in range(s)]
        trace = sum((M[i][m] * P[m][i] for i in range(s) for m in range(s)), zero)
        coef.append(-trace / k)
    return coef


class TableauPolynomials(NamedTuple):
    """``N`` and ``D`` of a tableau (:func:`exact_polynomials`), exact and as floats.

    ``N, D``: ``Fraction`` coefficients, ascending; ``exact``: whether every coefficient of the
    tableau was given exactly (else the floats' binary values were used); ``N_float,
    D_float``: each coefficient rounded once to the nearest float.
    """

    N: tuple[Fraction, ...]
    D: tuple[Fraction, ...]
    exact: bool
    N_float: np.ndarray
    D_float: np.ndarray


def exact_polynomials(A: Sequence[Sequence[Any]], b: Sequence[Any]) -> TableauPolynomials:
    """Return ``N`` and ``D`` of the coefficients as given, in ``Fraction`` arithmetic.

    Exact coefficients (``Fraction``, ints, sympy rationals, strings like ``"1/6"``) stay exact;
    floats and irrationals enter at their float's binary value.
    """
    pairs_A = [[as_fraction(v) for v in row] for row in A]
    pairs_b = [as_fraction(v) for v in b]
    exact = all(e for row in pairs_A for _, e in row) and all(e for _, e in pairs_b)
    N, D = stability_polynomials([[v for v, _ in row] for row in pairs_A], [v for v, _ in pairs_b])
    as_floats = [np.array([float(c) for c in p]) for p in (N, D)]
    for p in as_floats:
        p.flags.writeable = False
    return TableauPolynomials(tuple(N), tuple(D), exact, *as_floats)
