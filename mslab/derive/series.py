"""Power series in the step ``h``: the exact solutions' Taylor series (lecture notes, eqs. 4-5).

Two model problems, both autonomous and scalar:

* **first-order** ``y' = f(y)``, ``f`` a general smooth function given by its derivatives
  ``f, f', f'', ...`` at ``y_n`` (symbols :data:`F`);
* **second-order** ``x'' = a(x)``, with ``a, a', ...`` at ``x_n`` (symbols :data:`A`).
"""

from __future__ import annotations

from math import factorial
from typing import Any

import sympy as sp

from mslab.derive.coefficients import display

#: The step size, the independent variable of every expansion.
h = sp.Symbol("h", positive=True)
#: Position and velocity at t_n (second-order model problem).
x, v = sp.symbols("x v")
#: Stability variable z = lambda h.
z = sp.Symbol("z")
#: The value y(t_n) of the first-order problem.
y = sp.Symbol("y")

_MAX_DERIV = 12


def _names(base: str) -> tuple[sp.Symbol, ...]:
    primes = [base] + [base + "'" * k if k <= 3 else f"{base}^({k})" for k in range(1, _MAX_DERIV)]
    return tuple(sp.Symbol(p) for p in primes)


#: ``f, f', f'', ...`` at y_n (first-order problem y' = f(y)).
F = _names("f")
#: ``a, a', a'', ...`` at x_n (second-order problem x'' = a(x)).
A = _names("a")


def faithful(expr: sp.Expr) -> sp.Expr:
    """Floats in ``expr`` replaced by the fractions that round to exactly them (else kept).

    ``0.5 -> 1/2`` and ``1/6`` (as a float) ``-> 1/6``; a float that no fraction with a
    denominator up to 10^6 reproduces exactly stays a float.
    """
    floats = expr.atoms(sp.Float)
    if not floats:
        return expr
    return expr.xreplace({f: display(float(f)) for f in floats})


def trunc(expr: Any, n: int) -> sp.Expr:
    """Return ``expr`` expanded in powers of h, terms beyond ``h^n`` dropped."""
    expr = sp.expand(faithful(sp.sympify(expr)))
    return sp.Add(*[t for t in sp.Add.make_args(expr) if t.as_coeff_exponent(h)[1] <= n])


def coeff(expr: sp.Expr, k: int) -> sp.Expr:
    """Return the coefficient of ``h^k`` in ``expr``."""
    return sp.expand(expr).coeff(h, k)


def compose(derivs: tuple[sp.Symbol, ...], base: sp.Expr, arg: sp.Expr, n: int) -> sp.Expr:
    """Return the Taylor polynomial ``g(base + d) = sum_k g^(k) d^k / k!`` with ``d = arg - base = O(h)``."""
    d = trunc(arg - base, n)
    out, power = sp.Integer(0), sp.Integer(1)
    for k in range(n + 1):
        out += derivs[k] * power / factorial(k)
        power = trunc(power * d, n)
        if power == 0:
            break
    return trunc(out, n)


def _total_derivative(expr: sp.Expr, chain: dict):
    """d/dt of an expression in the symbols of ``chain`` (symbol -> its time derivative)."""
    return sp.expand(sum(sp.diff(expr, s) * ds for s, ds in chain.items()))


def derivatives(n: int, problem: str = "first") -> list:
    """Return the first ``n`` time derivatives of the exact solution at t_n.

    ``problem="first"``: ``y', y'', ...`` of ``y' = f(y)`` in ``f, f', ...``
    (``y'' = f' f``, ``y''' = f'' f^2 + f'^2 f``, ...).
    ``problem="second"``: ``x', x'', ...`` of ``x'' = a(x)`` in ``v, a, a', ...``.
    """
    if problem == "first":
        chain = {F[k]: F[k + 1] * F[0] for k in range(_MAX_DERIV - 1)}
        out = [F[0]]
    else:
        chain = {v: A[0], **{A[k]: A[k + 1] * v for k in range(_MAX_DERIV - 1)}}
        out = [v]
    while len(out) < n:
        out.append(_total_derivative(out[-1], chain))
    return out[:n]


def taylor(n: int, problem: str = "first", shift: sp.Expr = h) -> sp.Expr:
    """Return the exact solution at ``t + shift`` as a Taylor series through ``h^n`` (lecture notes, eq. 5).

    Parameters
    ----------
    n : int
        Highest power of h kept.
    problem : {"first", "second", "velocity"}
        ``"first"``: ``y(t + h) = y + h f + h^2/2 f' f + ...`` for ``y' = f(y)`` (symbol ``y``
        for ``y(t)``). ``"second"``: the position ``x(t + shift)`` of ``x'' = a(x)`` in
        ``x, v, a, a', ...`` at t; ``"velocity"``: ``v(t + shift)`` of the same problem.
    shift : sympy expression
        The time offset, a multiple of ``h`` (``-h`` for the backward series, eq. 22 of the lecture notes).

    Returns
    -------
    sympy expression
    """
    if problem == "first":
        y0, ds = y, derivatives(n, "first")
    elif problem == "second":
        y0, ds = x, derivatives(n, "second")
    elif problem == "velocity":
        y0, ds = v, derivatives(n + 1, "second")[1:]
    else:
        raise ValueError(f"problem must be 'first', 'second' or 'velocity', got {problem!r}")
    series = y0 + sum(ds[k - 1] * shift**k / factorial(k) for k in range(1, n + 1))
    return trunc(series, n)
