"""Sympy derivations: Taylor series, local errors and orders of the course's integrators.

Every method is checked against the exact Taylor series (seed eqs. 4-5) on one of three
model problems, and always from the coefficients or the code that steps:

* **first-order** ``y' = f(y)`` (scalar, autonomous, ``f`` a general smooth function
  given by its derivatives ``f, f', f'', ...`` at ``y_n``): explicit Runge-Kutta methods
  read their Butcher tableau ``A, b`` (the very arrays that step); implicit Euler
  (seed eq. 27, also when solved by fixed-point iteration, eq. 28) and the implicit
  midpoint rule are expanded order by order: the implicit relation is iterated as a
  power series in ``h``, each sweep fixes one more power.
* **second-order** ``x'' = a(x)`` (``a`` general, derivatives ``a, a', ...`` at
  ``x_n``): any other explicit integrator (symplectic Euler ×2, leapfrog, velocity
  Verlet, ...) is *run*: its own ``start`` and ``step`` are called on arrays of sympy
  expressions, and the new ``(x, v)`` is compared with the Taylor series of the exact
  solution.
* **two-step** (Verlet, seed eqs. 21-23): the formula
  ``x_{n+1} = 2 x_n - x_{n-1} + h^2 a(x_n)`` is fed the exact ``x(t - h), x(t)``; its
  residual is ``O(h^(p+2))`` for a method of order ``p`` (the ``h^2`` in front of the
  acceleration costs two powers).

The *local error* is ``y(t + h) - y_{n+1}`` when ``y_n = y(t)`` is exact: the part of
the Taylor series the method misses. A method has order ``p`` when it is
``O(h^(p+1))``. Scalar ``f`` is general enough up to order 4 (the first order
conditions that need systems appear at order 5).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from math import factorial

import numpy as np
import sympy as sp

from mslab.integrators.base import Integrator, get_method
from mslab.state import State

#: The step size, the independent variable of every expansion.
h = sp.Symbol("h", positive=True)
#: Position and velocity at t_n (second-order model problem).
x, v = sp.symbols("x v")
#: Stability variable z = lambda h.
z = sp.Symbol("z")

_MAX_DERIV = 12


def _names(base: str) -> tuple[sp.Symbol, ...]:
    primes = [base] + [base + "'" * k if k <= 3 else f"{base}^({k})" for k in range(1, _MAX_DERIV)]
    return tuple(sp.Symbol(p) for p in primes)


#: ``f, f', f'', ...`` at y_n (first-order problem y' = f(y)).
F = _names("f")
#: ``a, a', a'', ...`` at x_n (second-order problem x'' = a(x)).
A = _names("a")


# -- power series in h -----------------------------------------------------------------
def _rational(expr):
    """Replace float coefficients (0.5, 1/6 as a float) by the rationals they stand for."""
    floats = expr.atoms(sp.Float)
    if not floats:
        return expr
    return expr.xreplace({f: sp.nsimplify(f, tolerance=1e-12, rational=True) for f in floats})


def _trunc(expr, n: int):
    """``expr`` expanded in powers of h, terms beyond ``h^n`` dropped."""
    expr = sp.expand(_rational(sp.sympify(expr)))
    return sp.Add(*[t for t in sp.Add.make_args(expr) if t.as_coeff_exponent(h)[1] <= n])


def _coeff(expr, k: int):
    return sp.expand(expr).coeff(h, k)


def _compose(derivs: tuple[sp.Symbol, ...], base, arg, n: int):
    """Taylor polynomial ``g(base + d) = sum_k g^(k) d^k / k!`` with ``d = arg - base = O(h)``."""
    d = _trunc(arg - base, n)
    out, power = sp.Integer(0), sp.Integer(1)
    for k in range(n + 1):
        out += derivs[k] * power / factorial(k)
        power = _trunc(power * d, n)
        if power == 0:
            break
    return _trunc(out, n)


def _total_derivative(expr, chain: dict):
    """d/dt of an expression in the symbols of ``chain`` (symbol -> its time derivative)."""
    return sp.expand(sum(sp.diff(expr, s) * ds for s, ds in chain.items()))


def derivatives(n: int, problem: str = "first") -> list:
    """The first ``n`` time derivatives of the exact solution at t_n.

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


def taylor(n: int, problem: str = "first", shift=h):
    """Exact solution at ``t + shift`` as a Taylor series through ``h^n`` (seed eq. 5).

    Parameters
    ----------
    n : int
        Highest power of h kept.
    problem : {"first", "second", "velocity"}
        ``"first"``: ``y(t + h) = y + h f + h^2/2 f' f + ...`` for ``y' = f(y)`` (symbol ``y``
        for ``y(t)``). ``"second"``: the position ``x(t + shift)`` of ``x'' = a(x)`` in
        ``x, v, a, a', ...`` at t; ``"velocity"``: ``v(t + shift)`` of the same problem.
    shift : sympy expression
        The time offset, a multiple of ``h`` (``-h`` for the backward series, seed eq. 22).
    """
    if problem == "first":
        y0, ds = sp.Symbol("y"), derivatives(n, "first")
    elif problem == "second":
        y0, ds = x, derivatives(n, "second")
    elif problem == "velocity":
        y0, ds = v, derivatives(n + 1, "second")[1:]
    else:
        raise ValueError(f"problem must be 'first', 'second' or 'velocity', got {problem!r}")
    series = y0 + sum(ds[k - 1] * shift**k / factorial(k) for k in range(1, n + 1))
    return _trunc(series, n)


# -- the model problems, run symbolically ---------------------------------------------
class _Counters:
    n_force = n_jac = n_solve = n_iter = 0


class _SymbolicSystem:
    """Stands in for a System: one particle in 1D with acceleration ``a(x)`` as a series."""

    velocity_dependent = False
    dissipative = False

    def __init__(self, n: int):
        self.n = n
        self.counters = _Counters()

    def rhs(self, xs, vs):
        self.counters.n_force += 1
        a = np.empty_like(xs)
        for idx in np.ndindex(xs.shape):
            a[idx] = _compose(A, x, xs[idx], self.n)
        return a, 0

    def acceleration(self, xs, vs):
        return self.rhs(xs, vs)[0]


def _obj(value) -> np.ndarray:
    arr = np.empty((1, 1), dtype=object)
    arr[0, 0] = value
    return arr


def _rk_step(method, y0, f):
    """One step of the tableau on ``y' = f(y)``; ``f(y)`` returns a series (or exact value)."""
    Ar = [[_rational(sp.Float(a)) for a in row] for row in method.A]
    br = [_rational(sp.Float(b)) for b in method.b]
    stages = []
    for i in range(len(br)):
        yi = y0 + h * sum((Ar[i][j] * stages[j] for j in range(i)), sp.Integer(0))
        stages.append(f(yi))
    return y0 + h * sum(bi * k for bi, k in zip(br, stages, strict=True))


def _implicit_relation(method: Integrator):
    """The implicit one-step relation ``y1 = y0 + h f(point(y0, y1))``: the point."""
    if method.family == "implicit_rk" and method.A.shape == (1, 1) and method.b[0] == 1.0:
        g = _rational(sp.Float(method.A[0, 0]))
        return lambda y0, y1: y0 + g * (y1 - y0)      # seed eq. 27 for g = 1
    return None


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


def _first_nonzero(components, n: int) -> int | None:
    for k in range(n + 1):
        if any(_coeff(c, k) != 0 for c in components):
            return k
    return None


def analyse(method: str | Integrator, max_order: int = 5) -> Derivation:
    """Expand a method's step and the exact solution in powers of h and compare.

    Parameters
    ----------
    method : str or Integrator
        Registry name or an integrator (e.g. an ``ExplicitRK`` with your own tableau).
    max_order : int
        Orders up to this are detected (series through ``h^(max_order + 1)``, one more
        for the two-step formula).

    Returns
    -------
    Derivation

    Raises
    ------
    ValueError
        The error vanishes through the expansion (order above ``max_order``).
    TypeError
        An implicit method without a symbolic model here.
    """
    m = get_method(method)
    tableau = (m.A.tobytes(), m.b.tobytes()) if "A" in m.coefficients else None
    return _analyse(m, int(max_order), tableau)


@lru_cache(maxsize=64)
def _analyse(m: Integrator, max_order: int, tableau=None) -> Derivation:
    """``analyse`` for one method; ``tableau`` only keys the cache (a changed tableau is redone)."""
    n = max_order + (2 if m.family == "two_step" else 1)
    y0 = sp.Symbol("y")
    relation = _implicit_relation(m)
    if m.family == "explicit_rk" or relation is not None:
        problem = "first-order y' = f(y)"

        def f(y, k=n):
            return _compose(F, y0, y, k)

        if relation is not None:
            y1 = y0                              # iterate the relation: sweep k fixes h^k
            for k in range(1, n + 1):
                y1 = _trunc(y0 + h * f(relation(y0, y1), k - 1), k)
        else:
            y1 = _trunc(_rk_step(m, y0, f), n)
        error = _trunc(taylor(n, "first") - y1, n)
        components, shift = [error], 1
    elif not m.explicit:
        raise TypeError(f"{m.name}: no symbolic model of this implicit method (known: implicit Euler, "
                        "its fixed-point variant, implicit midpoint)")
    elif m.family == "two_step":
        problem = "two-step x'' = a(x)"
        system = _SymbolicSystem(n)
        state = State(_obj(x), _obj(v), (_obj(taylor(n, "second", -h)), 0))
        new = m.step(system, state, h)
        error = _trunc(taylor(n, "second") - new.x[0, 0], n)
        components, shift = [error], 2
    else:
        problem = "second-order x'' = a(x)"
        system = _SymbolicSystem(n)
        state = m.start(system, State(_obj(x), _obj(v)), h)
        new = m.step(system, state, h)
        ex = _trunc(taylor(n, "second") - new.x[0, 0], n)
        ev = _trunc(taylor(n, "velocity") - new.v[0, 0], n)
        error = sp.Matrix([ex, ev])
        components, shift = [ex, ev], 1
    k = _first_nonzero(components, n)
    if k is None:
        raise ValueError(f"{m.name}: local error vanishes through h^{n}; order > {max_order}")
    p = k - shift
    if isinstance(error, sp.Matrix):
        leading = sp.Matrix([sp.factor(_coeff(c, k)) * h**k for c in components])
    else:
        leading = sp.factor(_coeff(error, k)) * h**k
    return Derivation(m.name, problem, error, p, leading)


def order(method: str | Integrator, max_order: int = 5) -> int:
    """Order p of a method (local error ``O(h^(p+1))``) from its Taylor expansion."""
    return analyse(method, max_order).order


def local_error(method: str | Integrator, max_order: int = 5):
    """Leading term of the local error ``y(t + h) - y_{n+1}`` (see :func:`analyse`).

    Forward Euler: ``h**2*f*f'/2`` (the ``y''/2 h^2`` that seed eq. 6 drops).
    Second-order problem: ``Matrix([x term, v term])``; Verlet: the ``h^4`` residual
    of its two-step formula (seed eq. 23).
    """
    return analyse(method, max_order).leading


def stability_function(method: str | Integrator):
    """Amplification factor ``R(z)``, ``y_{n+1} = R(z) y_n`` on ``y' = lambda y`` (seed eq. 29).

    For first-order analysed methods (tableaux and the implicit ones): ``1 + z`` for
    forward Euler (seed eq. 32), ``1/(1 - z)`` for implicit Euler.
    """
    m = get_method(method)
    lam = sp.Symbol("lambda")
    y0 = sp.Integer(1)
    relation = _implicit_relation(m)
    if m.family == "explicit_rk":
        r = _rk_step(m, y0, lambda y: lam * y)
    elif relation is not None:
        y1 = sp.Symbol("y1")
        r = sp.solve(sp.Eq(y1, y0 + h * lam * relation(y0, y1)), y1)[0]
    else:
        raise TypeError(f"{m.name}: stability_function covers Runge-Kutta tableaux and implicit "
                        "one-step methods; see mslab.stability for the others")
    return sp.simplify(_rational(sp.expand(r)).subs(lam, z / h))


#: For Runge-Kutta tableaux ``R(z)`` is a polynomial (the name the lessons use).
stability_polynomial = stability_function

__all__ = ["A", "Derivation", "F", "analyse", "derivatives", "h", "local_error", "order",
           "stability_function", "stability_polynomial", "taylor", "v", "x", "z"]
