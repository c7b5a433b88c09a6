"""The imaginary stability limit of a Runge-Kutta tableau in exact rational arithmetic.

With ``R = N/D`` (``N(z) = det(I - zA + z 1 b^T)``, ``D(z) = det(I - zA)``),
``|R(iy)| <= 1`` is ``E(u) = |N(iy)|^2 - |D(iy)|^2 <= 0`` with ``u = y^2``, a polynomial of
degree ``s``. Its coefficients are computed here from the coefficients as given, as
``fractions.Fraction``: exact ones exactly, floats at their exact binary value. A
double-precision ``E`` of degree 20-32 cannot place its first root (SSP104's limit came out
as 4.925085 instead of 4.921453, with ``|R(iy)| > 1`` there); the exact one can, with
sympy's exact real root isolation (intervals with rational ends, refined to ``1e-18``).

When a coefficient is a float (or irrational), the coefficients of ``E`` that should vanish
only do so up to the coefficients' own rounding: those below ``64 eps`` times the size of
the products that form them (from ``|A|`` and ``|b|``) are set to zero. The size is
relative, never floored at 1: the top coefficients of ``E`` of a 10-stage method are about
``1e-14`` and real (flooring them at ``64 eps`` is what overstated SSP104's limit). Then the sign of the
lowest remaining coefficient decides small ``y`` (positive, however slightly: the limit 0),
and the smallest positive root of odd multiplicity (where ``E`` turns positive) is the
limit; a root of even multiplicity only touches zero.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction
from typing import Any

import numpy as np

_EPS = float(np.finfo(float).eps)


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
            from mslab.integrators.coefficients import to_float

            return Fraction(to_float(value)), False
    return Fraction(float(value)), False


def _det(rows: list[list[Fraction]]) -> Fraction:
    """Return the determinant, by Gaussian elimination in exact arithmetic."""
    a = [row[:] for row in rows]
    n, det = len(a), Fraction(1)
    for k in range(n):
        pivot = next((i for i in range(k, n) if a[i][k] != 0), None)
        if pivot is None:
            return Fraction(0)
        if pivot != k:
            a[k], a[pivot] = a[pivot], a[k]
            det = -det
        det *= a[k][k]
        for i in range(k + 1, n):
            f = a[i][k] / a[k][k]
            if f:
                for j in range(k, n):
                    a[i][j] -= f * a[k][j]
    return det


def _interpolate(values: list[Fraction]) -> list[Fraction]:
    """Coefficients (ascending) of the polynomial through ``(k, values[k])``, ``k = 0..n-1``."""
    n = len(values)
    coef = list(values)  # Newton's divided differences on the nodes 0, 1, ..., n-1
    for j in range(1, n):
        for i in range(n - 1, j - 1, -1):
            coef[i] = (coef[i] - coef[i - 1]) / j
    poly = [Fraction(0)] * n
    for i in range(n - 1, -1, -1):  # Horner: poly = poly * (z - i) + coef[i]
        poly = [(poly[k - 1] if k else Fraction(0)) - i * poly[k] for k in range(n)]
        poly[0] += coef[i]
    return poly


def rk_polynomials_exact(A: Sequence[Sequence[Fraction]], b: Sequence[Fraction]) -> tuple[list, list]:
    """``N(z)``, ``D(z)`` of a tableau, coefficients ascending, in exact arithmetic."""
    s = len(b)
    if all(A[i][j] == 0 for i in range(s) for j in range(i, s)):  # explicit: D = 1, N_k = b^T A^(k-1) 1
        N, w = [Fraction(1)], [Fraction(1)] * s
        for _ in range(s):
            N.append(sum((bi * wi for bi, wi in zip(b, w, strict=True)), Fraction(0)))
            w = [sum((A[i][j] * w[j] for j in range(s)), Fraction(0)) for i in range(s)]
        return N, [Fraction(1)]
    nums, dens = [], []
    for z in range(s + 1):
        base = [[Fraction(int(i == j)) - z * A[i][j] for j in range(s)] for i in range(s)]
        dens.append(_det(base))
        nums.append(_det([[base[i][j] + z * b[j] for j in range(s)] for i in range(s)]))
    return _interpolate(nums), _interpolate(dens)


def _mul(p: list, q: list) -> list:
    out = [0] * (len(p) + len(q) - 1)
    for i, pi in enumerate(p):
        if pi:
            for j, qj in enumerate(q):
                out[i + j] += pi * qj
    return out


def _abs2_on_axis(p: list) -> list:
    """``|p(iy)|^2`` as a polynomial in ``u = y^2`` (ascending): ``re(u)^2 + u im(u)^2``."""
    re = [p[k] * (-1) ** (k // 2) for k in range(0, len(p), 2)]
    im = [p[k] * (-1) ** (k // 2) for k in range(1, len(p), 2)] or [0]
    out = _mul(re, re)
    for k, c in enumerate(_mul(im, im)):
        out = out + [0] * (k + 2 - len(out))
        out[k + 1] += c
    return out


def _minus(p: list, q: list) -> list:
    n = max(len(p), len(q))
    return [(p[k] if k < len(p) else 0) - (q[k] if k < len(q) else 0) for k in range(n)]


def _size(p: list) -> np.ndarray:
    """Return the size of the products forming each coefficient of ``|p(iy)|^2`` in ``u``.

    For an explicit tableau ``p`` holds ``|b|^T |A|^(k-1) 1``, which bounds the rounding of
    the coefficients of ``N`` however they cancel; for an implicit one, ``|N_k|`` and ``|D_k|``.
    """
    a = np.abs(np.array([float(c) for c in p]))
    return np.convolve(a, a)[::2]


def imag_limit_exact(A: Sequence[Sequence[Any]], b: Sequence[Any]) -> float:
    """Largest ``y`` with ``|R(it)| <= 1`` for all ``|t| <= y`` (0: none, inf: whole axis)."""
    pairs_A = [[as_fraction(v) for v in row] for row in A]
    pairs_b = [as_fraction(v) for v in b]
    exact = all(e for row in pairs_A for _, e in row) and all(e for _, e in pairs_b)
    N, D = rk_polynomials_exact([[v for v, _ in row] for row in pairs_A], [v for v, _ in pairs_b])
    E = _minus(_abs2_on_axis(N), _abs2_on_axis(D))
    if not exact:  # coefficients that vanish for the intended method vanish only to rounding here
        absolute = [[abs(v) for v, _ in row] for row in pairs_A], [abs(v) for v, _ in pairs_b]
        N_abs, D_abs = rk_polynomials_exact(*absolute) if len(D) == 1 else (N, D)
        size = _size(N_abs) + np.pad(_size(D_abs), (0, len(N_abs) - len(D_abs)))
        E = [0 if abs(float(c)) <= 64 * _EPS * size[k] else c for k, c in enumerate(E)]
    nonzero = [k for k, c in enumerate(E) if c != 0]
    if not nonzero:
        return math.inf                     # |R(iy)| = 1 on the whole axis
    if E[nonzero[0]] > 0:
        return 0.0                          # |R(iy)| > 1 for small y, however slightly
    return _first_crossing([Fraction(c) for c in E[nonzero[0]:]])


def _first_crossing(F: list[Fraction]) -> float:
    """Return sqrt of the smallest positive root of odd multiplicity of ``F`` (``F(0) < 0``), or inf."""
    import sympy as sp

    u = sp.Symbol("u")
    poly = sp.Poly([sp.Rational(c.numerator, c.denominator) for c in reversed(F)], u, domain=sp.QQ)
    for (lo, hi), multiplicity in sorted(poly.intervals(), key=lambda r: r[0][0]):
        if hi <= 0 or multiplicity % 2 == 0:
            continue
        lo, hi = poly.refine_root(lo, hi, eps=sp.Rational(1, 10**18) * max(abs(hi), 1))
        return math.sqrt(float((lo + hi) / 2))
    return math.inf
