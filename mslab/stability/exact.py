"""The imaginary stability limit of a Runge-Kutta tableau in exact rational arithmetic.

With ``R = N/D`` (``N(z) = det(I - zA + z 1 b^T)``, ``D(z) = det(I - zA)``, from
:mod:`mslab.integrators.families.polynomials`), ``|R(iy)| <= 1`` is ``E(u) = |N(iy)|^2 - |D(iy)|^2 <= 0``
with ``u = y^2``, a polynomial of degree ``s``. Its coefficients are computed from the
coefficients as given, as ``fractions.Fraction``: exact ones exactly, floats at their exact
binary value. A
double-precision ``E`` of degree 20-32 cannot place its first root (SSP104's limit came out
as 4.925085 instead of 4.921453, with ``|R(iy)| > 1`` there); the exact one can, with
exact real-root isolation (Sturm sequences in rational arithmetic, refined to ``1e-18``).

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

from mslab.integrators.families.coefficients import as_fraction
from mslab.integrators.families.polynomials import (
    TableauPolynomials,
    exact_polynomials,
    stability_polynomials,
)

_EPS = float(np.finfo(float).eps)


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
    return imag_limit_of(exact_polynomials(A, b), A, b)


def imag_limit_of(p: TableauPolynomials, A: Sequence[Sequence[Any]], b: Sequence[Any]) -> float:
    """:func:`imag_limit_exact` from the tableau's polynomials ``p`` (``A``, ``b`` as given)."""
    N, D = list(p.N), list(p.D)
    E = _minus(_abs2_on_axis(N), _abs2_on_axis(D))
    if not p.exact:  # coefficients that vanish for the intended method vanish only to rounding here
        absolute = [[abs(as_fraction(v)[0]) for v in row] for row in A], [abs(as_fraction(v)[0]) for v in b]
        N_abs, D_abs = stability_polynomials(*absolute) if len(D) == 1 else (N, D)
        size = _size(N_abs) + np.pad(_size(D_abs), (0, len(N_abs) - len(D_abs)))
        E = [0 if abs(float(c)) <= 64 * _EPS * size[k] else c for k, c in enumerate(E)]
    nonzero = [k for k, c in enumerate(E) if c != 0]
    if not nonzero:
        return math.inf                     # |R(iy)| = 1 on the whole axis
    if E[nonzero[0]] > 0:
        return 0.0                          # |R(iy)| > 1 for small y, however slightly
    return _first_crossing([Fraction(c) for c in E[nonzero[0]:]])


def real_interval_of(p: TableauPolynomials, A: Sequence[Sequence[Any]], b: Sequence[Any]) -> float:
    """Left end ``-s`` of the real stability interval ``[-s, 0]`` of a tableau (``-inf``: whole axis).

    ``|R(-t)| <= 1`` is ``F(t) = N(-t)^2 - D(-t)^2 <= 0`` (a pole of ``R`` makes ``F > 0``);
    ``F(0) = 0``, so ``F(t) / t``, whose value at 0 is ``-2 R'(0)`` (negative for a consistent
    method), is examined; its smallest positive root where it turns positive, isolated
    exactly as for the imaginary limit, is ``s`` (0 when ``F / t`` starts positive). Float
    coefficients: coefficients of ``F`` at the rounding level of the products forming them
    are zero (a rounded ``|R(-inf)| = 1`` is no root near 1e15).
    """
    N, D = list(p.N), list(p.D)
    F = _minus(_mul(_reflect(N), _reflect(N)), _mul(_reflect(D), _reflect(D)))
    if not p.exact:
        absolute = [[abs(as_fraction(v)[0]) for v in row] for row in A], [abs(as_fraction(v)[0]) for v in b]
        N_abs, D_abs = stability_polynomials(*absolute) if len(D) == 1 else (N, D)
        a, d = (np.abs(np.array([float(c) for c in q])) for q in (N_abs, D_abs))
        size = np.convolve(a, a) + np.pad(np.convolve(d, d), (0, 2 * (len(a) - len(d))))
        F = [0 if abs(float(c)) <= 64 * _EPS * size[k] else c for k, c in enumerate(F)]
    nonzero = [k for k, c in enumerate(F) if c != 0]
    if not nonzero:
        return -math.inf                    # |R| = 1 on the whole axis
    if F[nonzero[0]] > 0:
        return 0.0
    root = _first_root([Fraction(c) for c in F[nonzero[0]:]])
    return -math.inf if root is None else -float(root)


def _reflect(p: list) -> list:
    """Coefficients of ``p(-t)`` (ascending)."""
    return [c * (-1) ** k for k, c in enumerate(p)]


def _first_crossing(F: list[Fraction]) -> float:
    """Return sqrt of the smallest positive root of odd multiplicity of ``F`` (``F(0) < 0``), or inf."""
    root = _first_root(F)
    return math.inf if root is None else math.sqrt(float(root))


def _first_root(F: list[Fraction]) -> Fraction | None:
    """Return the smallest positive root of odd multiplicity of ``F`` (``F(0) < 0``), or None.

    Exact real-root isolation in rational arithmetic (``fractions.Fraction``, no sympy): the
    Sturm sequence of the square-free part ``G = F / gcd(F, F')`` counts the distinct roots
    in an interval; bisection isolates them in increasing order and refines each to a
    relative width of 1e-18; a root is a crossing where ``F`` changes sign across it (odd
    multiplicity), not where it only touches zero.
    """
    G = _quotient(F, _gcd(F, _derivative(F)))
    if len(G) == 1:
        return None                                     # no real root at all
    sturm = _sturm(G)
    bound = 1 + max(abs(c / G[-1]) for c in G[:-1])   # Cauchy: every root below it
    lo = Fraction(0)
    while _count(sturm, lo, bound) > 0:
        hi = bound
        while _count(sturm, lo, hi) > 1:                # isolate the next root in (lo, hi]
            mid = (lo + hi) / 2
            if _count(sturm, lo, mid) >= 1:
                hi = mid
            else:
                lo = mid
        a, b = lo, hi                                   # one simple root of G in (a, b]
        while b - a > Fraction(1, 10**18) * b:
            mid = (a + b) / 2
            if _sign(_eval(G, mid)) == 0:
                a = b = mid
                break
            if _sign(_eval(G, mid)) == _sign(_eval(G, a)) and _eval(G, a) != 0:
                a = mid
            else:
                b = mid
        root = (a + b) / 2
        width = max(b - a, Fraction(1, 10**30) * max(root, Fraction(1)))
        if _sign(_eval(F, root - width)) != _sign(_eval(F, root + width)):
            return root
        lo = b                                          # a touching root: look further out
    return None


def _eval(p: list[Fraction], x: Fraction) -> Fraction:
    out = Fraction(0)
    for c in reversed(p):
        out = out * x + c
    return out


def _sign(x: Fraction) -> int:
    return (x > 0) - (x < 0)


def _derivative(p: list[Fraction]) -> list[Fraction]:
    return [k * c for k, c in enumerate(p)][1:] or [Fraction(0)]


def _trim(p: list[Fraction]) -> list[Fraction]:
    while len(p) > 1 and p[-1] == 0:
        p = p[:-1]
    return p


def _divmod(p: list[Fraction], q: list[Fraction]) -> tuple[list[Fraction], list[Fraction]]:
    """Polynomial division with remainder (ascending coefficients, ``q`` trimmed, nonzero)."""
    p = _trim(list(p))
    if len(p) < len(q):
        return [Fraction(0)], p
    out = [Fraction(0)] * (len(p) - len(q) + 1)
    for k in range(len(out) - 1, -1, -1):
        c = p[k + len(q) - 1] / q[-1]
        out[k] = c
        for j, qc in enumerate(q):
            p[k + j] -= c * qc
    return out, _trim(p[: len(q) - 1] or [Fraction(0)])


def _quotient(p: list[Fraction], q: list[Fraction]) -> list[Fraction]:
    return _trim(_divmod(p, _trim(q))[0])


def _gcd(p: list[Fraction], q: list[Fraction]) -> list[Fraction]:
    a, b = _trim(list(p)), _trim(list(q))
    while not (len(b) == 1 and b[0] == 0):
        a, b = b, _divmod(a, b)[1]
    return [c / a[-1] for c in a]


def _sturm(p: list[Fraction]) -> list[list[Fraction]]:
    seq = [_trim(p), _trim(_derivative(p))]
    while not (len(seq[-1]) == 1 and seq[-1][0] == 0) and len(seq[-1]) > 1:
        seq.append([-c for c in _divmod(seq[-2], seq[-1])[1]])
    return [s for s in seq if not (len(s) == 1 and s[0] == 0)]


def _changes(sturm: list[list[Fraction]], x: Fraction) -> int:
    signs = [s for s in (_sign(_eval(p, x)) for p in sturm) if s != 0]
    return sum(1 for a, b in zip(signs, signs[1:], strict=False) if a != b)


def _count(sturm: list[list[Fraction]], lo: Fraction, hi: Fraction) -> int:
    """Distinct roots of the square-free polynomial in ``(lo, hi]`` (Sturm's theorem)."""
    return _changes(sturm, lo) - _changes(sturm, hi)
