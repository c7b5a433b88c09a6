"""Stability limits along rays: the real interval, the imaginary limit, the oscillator limit.

* Runge-Kutta methods: the imaginary limit and the real interval are exact
  (:mod:`mslab.stability.exact`; on the real axis ``|R(-t)| <= 1`` is
  ``N(-t)^2 - D(-t)^2 <= 0``, whose first crossing is isolated the same way, at any size:
  no narrow unstable gap is stepped over, no interval is capped). With
  ``R = N/D`` (``N(z) = det(I - zA + z 1 b^T)``, ``D(z) = det(I - zA)``), ``|R(iy)| <= 1`` is
  ``E(y) = |N(iy)|^2 - |D(iy)|^2 <= 0``, an even polynomial, formed in rational arithmetic
  from the coefficients as given. For float coefficients, coefficients of ``E`` at their
  rounding level (relative to the size of the products that form them) are zero; then the
  sign of the lowest remaining one decides small ``y`` — positive, however slightly, means
  the limit 0 (forward Euler, Heun, and methods of order 5 and higher such as
  Dormand-Prince) — and the smallest positive root where ``E`` turns positive, isolated
  exactly, is the limit. On the undamped oscillator the map has eigenvalues
  ``R(+-i dt w)``, so the oscillator limit is the imaginary limit.
* Every other limit is found on the method's own map: a scan of the ray
  ``|dt lam| in [S_MIN, S_MAX]`` (then bisection) with ``rho <= 1 + TOL``, where ``TOL``
  only absorbs the round-off of eigenvalues near a double eigenvalue (the end of the
  symplectic methods' interval); a method unstable at ``S_MIN`` gets 0, one stable up to
  ``S_MAX`` gets inf.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from functools import lru_cache

import numpy as np

from mslab.integrators.base import Integrator, get_method
from mslab.integrators.families.polynomials import exact_polynomials
from mslab.stability.exact import imag_limit_of, real_interval_of
from mslab.stability.functions import amplification, amplification_matrix, spectral_radius, tableau
from mslab.stability.gaps import boundary, first_unstable

#: ``rho <= 1 + TOL`` counts as stable in the scans (round-off of near-defective eigenvalues).
TOL = 1e-10
#: Smallest ``|dt lam|`` examined by a scan; a method unstable there gets the limit 0.
S_MIN = 1e-2
#: Largest ``|dt lam|`` examined; a method stable up to here gets the limit inf.
S_MAX = 1e6
_GRID = np.geomspace(S_MIN, S_MAX, 1201)


def _ray_limit(rho: Callable[[np.ndarray], np.ndarray], chunk: int = 100,
               functions: Callable[[np.ndarray], np.ndarray] | None = None) -> float:
    """Largest s with ``rho(s') <= 1 + TOL`` for all s' in [S_MIN, s] (0 / inf at the ends).

    ``functions``: the ray's boundary functions (:func:`mslab.stability.gaps.boundary`); with
    them, an unstable gap narrower than the grid below its first unstable point is found
    (:func:`mslab.stability.gaps.first_unstable`) and the first edge is that gap's.
    """
    first = None
    for start in range(0, _GRID.size, chunk):
        bad = np.flatnonzero(~(rho(_GRID[start:start + chunk]) <= 1.0 + TOL))
        if bad.size:
            first = start + int(bad[0])
            break
    if first is None:
        return np.inf
    if first == 0:
        return 0.0
    lo, hi = _GRID[first - 1], _GRID[first]
    gap = None if functions is None else first_unstable(rho, functions, float(hi), S_MIN, TOL)
    if gap is not None:
        lo, hi = gap
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if rho(np.array([mid]))[0] <= 1.0 + TOL:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return float(lo)


def rk_polynomials(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients (ascending, length s + 1) of ``N(z) = det(I - zA + z 1 b^T)``, ``D(z) = det(I - zA)``.

    Of the float arrays as given, exactly (:func:`mslab.integrators.families.polynomials.exact_polynomials`),
    each coefficient rounded once.
    """
    p = exact_polynomials(np.asarray(A, dtype=float).tolist(), np.asarray(b, dtype=float).tolist())
    s = len(b)
    return np.pad(p.N_float, (0, s + 1 - len(p.N))), np.pad(p.D_float, (0, s + 1 - len(p.D)))


@lru_cache(maxsize=256)
def _real_interval(m: Integrator) -> float:
    if tableau(m) is not None:  # exactly, from the coefficients as given
        return real_interval_of(m.polynomials, m.coefficients["A"], m.coefficients["b"])
    return scanned_real_interval(m)


def scanned_real_interval(m: Integrator) -> float:
    """Return the real interval's left end scanned on ``|R(-s)|`` (splittings, two-step forms)."""
    return -_ray_limit(lambda s: np.abs(amplification(m, -s)), functions=boundary(m, np.array([-1.0])))


@lru_cache(maxsize=256)
def _imag_limit(m: Integrator) -> float:
    if tableau(m) is not None:  # exactly, from the coefficients as given
        return imag_limit_of(m.polynomials, m.coefficients["A"], m.coefficients["b"])
    return _ray_limit(lambda s: np.maximum(np.abs(amplification(m, 1j * s)),
                                           np.abs(amplification(m, -1j * s))),
                      functions=boundary(m, np.array([1j])))


@lru_cache(maxsize=256)
def _oscillator_limit(m: Integrator) -> float:
    if tableau(m) is not None:
        return _imag_limit(m)
    return _ray_limit(lambda s: spectral_radius(amplification_matrix(m, s)),
                      functions=boundary(m, np.array([1j])))


def real_interval(method: str | Integrator) -> float:
    """Left end ``a`` of the real stability interval ``[a, 0]`` (``-inf``: whole negative axis).

    For splittings and the two-step forms the ray is the critically damped oscillator
    (see :mod:`mslab.stability.functions`).
    """
    return _real_interval(get_method(method))


def imag_limit(method: str | Integrator) -> float:
    """Largest ``y`` with ``|R(i t)| <= 1`` for all ``|t| <= y`` (0: none, inf: whole axis)."""
    return _imag_limit(get_method(method))


def oscillator_limit(method: str | Integrator) -> float:
    """Supremum of the ``dt * w`` for which the method is stable on ``x'' = -w^2 x``.

    0 for forward Euler (never stable undamped), 2 for symplectic Euler and Verlet (stable
    for ``dt w < 2``; at 2 the map is a Jordan block), ``2 sqrt 2`` for RK4, about 1.5734 for
    Forest-Ruth, inf for the A-stable implicit methods.
    """
    return _oscillator_limit(get_method(method))


def summary(methods: Iterable[str | Integrator] | None = None) -> list[dict]:
    """Real interval, imaginary limit and oscillator limit for each method (a table's rows)."""
    from mslab.integrators.base import methods as all_methods

    names = all_methods() if methods is None else [get_method(m).name for m in methods]
    rows = []
    for name in names:
        m = get_method(name)
        rows.append({"method": name, "explicit": bool(m.explicit), "order": int(m.order),
                     "real_interval": real_interval(m), "imag_limit": imag_limit(m),
                     "oscillator_limit": oscillator_limit(m)})
    return rows
