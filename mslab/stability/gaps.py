"""Narrow unstable gaps on a ray: where the stability of an explicit method can change, found as roots.

A scan of ``rho(s)`` on a grid steps over an unstable gap narrower than its spacing (yoshida6
on a mode with damping ratio 0.04: unstable for ``dt w`` in [2.2962, 2.3022], stable again
up to 2.8189, which the scan reported). Along a ray ``dt lam = s u`` an explicit method's
step is polynomial in ``s``, and its stability can only change where a polynomial
**boundary function** of ``s`` vanishes:

* a Runge-Kutta tableau: ``|R(s u)|^2 - 1`` (``R`` a polynomial);
* a method with an oscillator map ``M(s)`` (2 x 2 or 3 x 3, entries polynomial in ``s``),
  characteristic polynomial ``mu^k + a_{k-1} mu^{k-1} + ... + a_0``: an eigenvalue crosses
  the unit circle at ``mu = 1`` (``p(1) = 0``), at ``mu = -1`` (``p(-1) = 0``) or as a
  complex pair ``e^{+-i theta}`` — ``a_0 = 1`` for ``k = 2``,
  ``1 - a_0^2 + a_0 a_2 - a_1 = 0`` for ``k = 3`` (the cubic with the factor
  ``mu^2 - 2 cos(theta) mu + 1``).

Each boundary function is interpolated exactly (up to round-off) on Chebyshev points of
``[0, s_scan]`` (the scan's first unstable point; below it the map's entries stay moderate,
and the interval is halved where the interpolant does not converge); its real roots (and the
real parts of nearly real complex roots: a near-double root, the edges of a very narrow
gap, may come out as a complex pair)
are the only places where the stability can change. Between two consecutive ones it is the
same everywhere, so testing ``rho`` at each root and at each midpoint finds the first
unstable point below the grid's.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.polynomial import chebyshev as cheb

from mslab.integrators.base import Integrator

#: Chebyshev points per piece of the ray: exact for boundary functions of degree < NODES
NODES = 96
#: halvings of the ray's interval at most, where a boundary function's interpolant does not converge
SPLITS = 6
#: a piece's Chebyshev coefficients must fall below this fraction of the largest (else not polynomial)
CONVERGED = 1e-11
#: Chebyshev coefficients below this times the values' size are round-off
ROUNDING = 64 * float(np.finfo(float).eps)
#: complex roots with ``|Im| <= NEAR_REAL * piece width`` count as (near-double) real roots
NEAR_REAL = 1e-3


def boundary(m: Integrator, units: np.ndarray) -> Callable[[np.ndarray], np.ndarray] | None:
    """Return ``f(s) -> (n_functions, len(s))``: the boundary functions on the rays ``s * units``.

    ``units``: complex directions ``dt lam / s`` (``|u| = 1``). None for a method whose step is
    not polynomial in ``s`` (an implicit tableau) or whose map is larger than 3 x 3.
    """
    units = np.atleast_1d(np.asarray(units, dtype=complex))
    if not m.explicit:
        return None
    if m.stability_function(np.zeros(1, dtype=complex)) is not None:
        if len(m.polynomials.D) != 1:
            return None
        return lambda s: (np.abs(m.stability_function(s[None, :] * units[:, None])) ** 2 - 1.0)
    k = m.oscillator_matrix(np.ones(1), np.zeros(1)).shape[-1]
    if k not in (2, 3):
        return None

    def functions(s: np.ndarray) -> np.ndarray:
        M = m.oscillator_matrix(s[None, :] * np.abs(units)[:, None], -2.0 * s[None, :] * units.real[:, None])
        a = _characteristic(M)  # a[..., j]: coefficient of mu^j, monic
        at_one, at_minus = a.sum(axis=-1), (a * (-1.0) ** np.arange(k + 1)).sum(axis=-1)
        pair = a[..., 0] - 1.0 if k == 2 else 1.0 - a[..., 0] ** 2 + a[..., 0] * a[..., 2] - a[..., 1]
        return np.concatenate([at_one, at_minus, pair])

    return functions


def _characteristic(M: np.ndarray) -> np.ndarray:
    """Coefficients (ascending, monic) of ``det(mu I - M)`` of a stack of 2 x 2 or 3 x 3 matrices."""
    tr = np.trace(M, axis1=-2, axis2=-1)
    det = np.linalg.det(M)
    one = np.ones_like(tr)
    if M.shape[-1] == 2:
        return np.stack([det, -tr, one], axis=-1)
    minors = (M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
              + M[..., 0, 0] * M[..., 2, 2] - M[..., 0, 2] * M[..., 2, 0]
              + M[..., 1, 1] * M[..., 2, 2] - M[..., 1, 2] * M[..., 2, 1])
    return np.stack([-det, minors, -tr, one], axis=-1)


def first_unstable(rho: Callable[[np.ndarray], np.ndarray], functions: Callable[[np.ndarray], np.ndarray],
                   hi: float, lowest: float, tol: float) -> tuple[float, float] | None:
    """Return ``(lo, up)``: ``rho(lo)`` stable, ``rho(up)`` not, ``up`` the first unstable test point.

    ``hi``: a point known unstable (the scan's); test points lie in ``[lowest, hi)`` (below
    ``lowest`` the map is near a defective eigenvalue 1 and ``rho`` is round-off). None when
    every test point is stable (the first unstable point is then between the scan's last
    stable one and ``hi``), or when a boundary function is not a polynomial of degree below
    :data:`NODES` on a piece of ``[0, hi]`` halved :data:`SPLITS` times.
    """
    roots = _roots(functions, 0.0, hi, SPLITS)
    if roots is None:
        return None
    cand = np.unique(roots[(roots > lowest) & (roots < hi)])
    tests = np.unique(np.concatenate([[lowest], cand, 0.5 * (cand[1:] + cand[:-1])]))
    bad = np.flatnonzero(~(rho(tests) <= 1.0 + tol))
    if bad.size == 0:
        return None
    j = int(bad[0])
    return (float(tests[j - 1]) if j else 0.0), float(tests[j])


def _roots(functions: Callable[[np.ndarray], np.ndarray], a: float, b: float,
           splits: int) -> np.ndarray | None:
    """Roots in ``[a, b]`` of every boundary function, the interval halved where one does not converge."""
    roots = _piece_roots(functions, a, b)
    if roots is not None or splits == 0:
        return roots
    mid = 0.5 * (a + b)
    left, right = _roots(functions, a, mid, splits - 1), _roots(functions, mid, b, splits - 1)
    return None if left is None or right is None else np.concatenate([left, right])


#: Chebyshev points of the first kind, and the map from values there to the interpolant's coefficients
_X = np.cos(np.pi * (np.arange(NODES) + 0.5) / NODES)
_TO_COEFFICIENTS = (2.0 / NODES) * np.cos(np.outer(np.arange(NODES), np.arccos(_X)))
_TO_COEFFICIENTS[0] *= 0.5


def _piece_roots(functions: Callable[[np.ndarray], np.ndarray], a: float, b: float) -> np.ndarray | None:
    """Real (and nearly real) roots in ``[a, b]`` of every boundary function; None: not polynomial."""
    s = a + (b - a) * 0.5 * (_X + 1.0)
    values = functions(s)
    noise = ROUNDING * max(float(np.max(np.abs(values))), 1.0)  # the map's entries are O(1) or more
    found = []
    for f in values:
        c = _TO_COEFFICIENTS @ f
        top = float(np.max(np.abs(c)))
        if top <= noise:  # identically zero to round-off (det = 1 of a symplectic map)
            continue
        if np.max(np.abs(c[-8:])) > max(CONVERGED * top, noise):
            return None
        c = c[: int(np.flatnonzero(np.abs(c) > noise)[-1]) + 1]
        if c.size < 2:
            continue
        r = cheb.chebroots(c)
        r = r[(np.abs(r.imag) <= NEAR_REAL * 2.0) & (np.abs(r.real) <= 1.0)].real
        found.append(a + (b - a) * 0.5 * (r + 1.0))
    return np.concatenate(found) if found else np.zeros(0)
