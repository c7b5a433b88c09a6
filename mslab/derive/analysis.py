"""Orders, local errors and stability functions of methods, read from their coefficients.

``order`` comes from the rooted-tree order conditions (:mod:`mslab.derive.conditions`):
right for any tableau and any order up to ``max_order``. ``analyse`` adds the local error
on a scalar model problem, ``y(t + h) - y_{n+1}`` when ``y_n = y(t)`` is exact: the part of
the Taylor series the method misses. A method of order ``p`` has a local error
``O(h^(p+1))``; its ``h^(p+1)`` term is the *leading* term. A scalar problem does not
separate all elementary differentials beyond order 4, so for some methods of order 4 and
up the leading term shown may vanish on it while a system problem still sees it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import sympy as sp

from mslab.derive.coefficients import display
from mslab.derive.conditions import OrderAboveLimit, rk_order, splitting_order
from mslab.derive.reading import Reading, read
from mslab.derive.runs import rk_series, run_series, splitting_series
from mslab.derive.series import coeff, h, taylor, trunc, z
from mslab.integrators.families.polynomials import stability_polynomials

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator

_CACHE: dict = {}


@dataclass
class Derivation:
    """What ``analyse`` found for one method.

    Attributes
    ----------
    method : str
    problem : str
        ``"first-order y' = f(y)"``, ``"second-order x'' = a(x)"`` or ``"two-step x'' = a(x)"``.
    error : sympy expression or sympy Matrix
        Local error series (exact minus method) through ``h^n``: a scalar for the first-order
        problem and the two-step formula, ``Matrix([x error, v error])`` for the second-order one.
    order : int
        Global order p.
    leading : sympy expression or Matrix
        The ``h^(p+1)`` term of ``error`` (``h^(p+2)`` for the two-step formula).
    """

    method: str
    problem: str
    error: object
    order: int
    leading: object


def _too_high(name: str, max_order: int) -> ValueError:
    return ValueError(f"{name}: the order conditions hold through order {max_order + 1}; "
                      f"order > {max_order}")


def _coefficient_order(r: Reading, max_order: int) -> int:
    try:
        if r.kind == "rk":
            return rk_order(r.A, r.b, max_order)
        return splitting_order(r.drift, r.kick, max_order)
    except OrderAboveLimit:
        raise _too_high(r.name, max_order) from None


def order(method: str | Integrator, max_order: int = 8) -> int:
    """Order p of a method (global error ``O(h^p)``, local error ``O(h^(p+1))``).

    Runge-Kutta tableaux (explicit or implicit): Butcher's conditions over all rooted trees
    with up to ``p + 1`` vertices, on the coefficients as given (exact ones exactly, floats
    up to round-off). Splittings: the conditions of the equivalent partitioned method on
    ``x' = v, v' = a(x)``. Two-step and staggered adapters: the order of their splitting.

    Parameters
    ----------
    method : str or method object
        Registry name or a method (e.g. ``ExplicitRK`` with your own tableau).
    max_order : int
        Orders up to this are detected.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        The order is above ``max_order``.
    """
    r = read(method)
    if r.kind == "run" and r.splitting is not None:
        r = r.splitting
    if r.kind == "run":
        return analyse(r.method, max_order).order
    return _coefficient_order(r, int(max_order))


def analyse(method: str | Integrator, max_order: int = 5) -> Derivation:
    """Expand a method's step and the exact solution in powers of h and compare.

    Parameters
    ----------
    method : str or method object
        Registry name or a method (e.g. an ``ExplicitRK`` with your own tableau).
    max_order : int
        Orders up to this are detected (series through ``h^(max_order + 1)``, one more
        for the two-step formula).

    Returns
    -------
    Derivation

    Raises
    ------
    ValueError
        The order is above ``max_order``.
    TypeError
        An implicit method without coefficients.
    """
    r = read(method)
    key = (r.key(), int(max_order))
    if key not in _CACHE:
        if len(_CACHE) > 64:
            _CACHE.clear()
        _CACHE[key] = _analyse(r, int(max_order))
    return _CACHE[key]


def _first_nonzero(components: Sequence[sp.Expr], n: int) -> int | None:
    for k in range(n + 1):
        if any(coeff(c, k) != 0 for c in components):
            return k
    return None


def _analyse(r: Reading, max_order: int) -> Derivation:
    shift = 1
    if r.kind == "rk":
        n = max_order + 1
        problem = "first-order y' = f(y)"
        components = [trunc(taylor(n, "first") - rk_series(r.A, r.b, n), n)]
    elif r.kind == "splitting":
        n = max_order + 1
        problem = "second-order x'' = a(x)"
        xs, vs = splitting_series(r.drift, r.kick, n)
        components = [trunc(taylor(n, "second") - xs, n), trunc(taylor(n, "velocity") - vs, n)]
    elif getattr(r.method, "explicit", True) is False:
        raise TypeError(f"{r.name}: an implicit method without coefficients; mslab.derive reads "
                        "implicit methods from their Butcher tableau (coefficients['A'], ['b'])")
    else:
        shift = 2 if r.two_step else 1
        n = max_order + shift
        run = run_series(r.method, n, r.two_step)
        if r.two_step:
            problem = "two-step x'' = a(x)"
            components = [trunc(taylor(n, "second") - run[0], n)]
        else:
            problem = "second-order x'' = a(x)"
            components = [trunc(taylor(n, "second") - run[0], n), trunc(taylor(n, "velocity") - run[1], n)]
    if r.kind == "run":
        k = _first_nonzero(components, n)
        if k is None:
            raise ValueError(f"{r.name}: local error vanishes through h^{n}; order > {max_order}")
        p = k - shift
    else:
        p = _coefficient_order(r, max_order)
        k = p + 1
    leading = [sp.factor(coeff(c, k)) * h**k for c in components]
    if len(components) == 1:
        return Derivation(r.name, problem, components[0], p, leading[0])
    return Derivation(r.name, problem, sp.Matrix(components), p, sp.Matrix(leading))


def local_error(method: str | Integrator, max_order: int = 5) -> sp.Expr:
    """Leading term of the local error ``y(t + h) - y_{n+1}`` (see :func:`analyse`).

    Forward Euler: ``h**2*f*f'/2`` (the ``y''/2 h^2`` that eq. 6 of the lecture notes drops).
    Second-order problem: ``Matrix([x term, v term])``; Verlet: the ``h^4`` residual
    of its two-step formula (lecture notes, eq. 23).
    """
    return analyse(method, max_order).leading


def stability_function(method: str | Integrator) -> sp.Expr:
    """Amplification factor ``R(z)``, ``y_{n+1} = R(z) y_n`` on ``y' = lambda y`` (lecture notes, eq. 29).

    ``R(z) = det(I - z A + z 1 b^T) / det(I - z A)`` from the Butcher tableau, explicit or
    implicit (:func:`mslab.integrators.families.polynomials.stability_polynomials` in sympy numbers),
    exact when the coefficients are: ``1 + z`` for forward Euler (lecture notes, eq. 32),
    ``1/(1 - z)`` for implicit Euler. ``z`` is :data:`mslab.derive.z`.

    Raises
    ------
    TypeError
        The method is not a Runge-Kutta tableau (see ``mslab.stability`` for the others).
    """
    r = read(method)
    if r.kind != "rk":
        raise TypeError(f"{r.name}: stability_function covers Runge-Kutta tableaux; "
                        "see mslab.stability for the other methods")
    N, D = stability_polynomials([[display(a) for a in row] for row in r.A], [display(w) for w in r.b])
    num = sp.expand(sum(sp.expand(c) * z**k for k, c in enumerate(N)))
    den = sp.expand(sum(sp.expand(c) * z**k for k, c in enumerate(D)))
    return sp.simplify(num / den)
