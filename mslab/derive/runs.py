"""One step of a method on a model problem, as power series in ``h``.

From coefficients: a Runge-Kutta tableau on ``y' = f(y)`` (its stage equations solved as
power series, each sweep fixing one more power of ``h``: one sweep in stage order for an
explicit tableau), a drift/kick splitting on ``x'' = a(x)``. Or from the method's own code:
its ``start`` and ``step`` are called on arrays of sympy expressions (a symbolic stand-in
for a System), for methods that carry no coefficients.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp

from mslab.derive.coefficients import display
from mslab.derive.series import A as A_SYM
from mslab.derive.series import F, compose, h, taylor, trunc, v, x, y
from mslab.state import State

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator


def _placeholders(values: list[sp.Expr], subs: dict) -> list[sp.Expr]:
    """Irrational coefficients replaced by symbols (kept in ``subs``): the series stay cheap."""
    out = []
    for value in values:
        if value.is_Rational or value.is_Float:
            out.append(value)
        else:
            out.append(subs.setdefault(value, sp.Symbol(f"_c{len(subs)}")))
    return out


def _restore(expr: sp.Expr, subs: dict) -> sp.Expr:
    return sp.expand(expr.xreplace({s: value for value, s in subs.items()})) if subs else expr


def _explicit(A: list[list[sp.Expr]]) -> bool:
    return all(A[i][j] == 0 for i in range(len(A)) for j in range(i, len(A)))


def rk_series(A: Sequence[Sequence[Any]], b: Sequence[Any], n: int) -> sp.Expr:
    """Return ``y_{n+1}`` of the tableau ``A, b`` on ``y' = f(y)`` through ``h^n``."""
    subs: dict = {}
    Ad = [[display(a) for a in row] for row in A]
    bd = [display(w) for w in b]
    explicit = _explicit(Ad)
    if explicit:  # an implicit tableau needs its products simplified as it sweeps
        Ad = [_placeholders(row, subs) for row in Ad]
        bd = _placeholders(bd, subs)
    s = len(bd)

    stages = [y] * s
    slopes = [F[0]] * s
    # explicit: one sweep in stage order; implicit: sweep k fixes the h^k terms
    for k in [n] if explicit else range(1, n + 1):
        for i in range(s):
            stages[i] = trunc(y + h * sum((Ad[i][j] * slopes[j] for j in range(s) if Ad[i][j] != 0),
                                          sp.Integer(0)), k)
            slopes[i] = compose(F, y, stages[i], k)
    y1 = y + h * sum((bi * ki for bi, ki in zip(bd, slopes, strict=True)), sp.Integer(0))
    return _restore(trunc(y1, n), subs)


def splitting_series(drift: Sequence[Any], kick: Sequence[Any], n: int) -> tuple[sp.Expr, sp.Expr]:
    """Return ``(x_{n+1}, v_{n+1})`` of the drift-first splitting on ``x'' = a(x)`` through ``h^n``."""
    subs: dict = {}
    drift = _placeholders([display(a) for a in drift], subs)
    kick = _placeholders([display(b) for b in kick], subs)
    xs, vs = x, v
    for i, a in enumerate(drift):
        xs = trunc(xs + a * h * vs, n)
        if i < len(kick):
            vs = trunc(vs + kick[i] * h * compose(A_SYM, x, xs, n), n)
    return _restore(xs, subs), _restore(vs, subs)


class _Counters:
    n_force = n_jac = n_solve = n_iter = 0


class _SymbolicSystem:
    """Stands in for a System: one particle in 1D with acceleration ``a(x)`` as a series."""

    velocity_dependent = False
    dissipative = False

    def __init__(self, n: int) -> None:
        self.n = n
        self.counters = _Counters()

    def rhs(self, xs: np.ndarray, vs: np.ndarray):
        self.counters.n_force += 1
        a = np.empty_like(xs)
        for idx in np.ndindex(xs.shape):
            a[idx] = compose(A_SYM, x, xs[idx], self.n)
        return a, 0

    def acceleration(self, xs: np.ndarray, vs: np.ndarray):
        return self.rhs(xs, vs)[0]


def _obj(value: Any) -> np.ndarray:
    arr = np.empty((1, 1), dtype=object)
    arr[0, 0] = value
    return arr


def run_series(method: Integrator, n: int, two_step: bool) -> tuple[sp.Expr, ...]:
    """Run the method's own step on ``x'' = a(x)`` through ``h^n``.

    Two-step methods are fed the exact ``x(t - h), x(t)`` and return ``(x_{n+1},)``; the
    others start from ``(x, v)`` and return ``(x_{n+1}, v_{n+1})``.
    """
    system = _SymbolicSystem(n)
    if two_step:
        state = State(_obj(x), _obj(v), (_obj(taylor(n, "second", -h)), 0))
        new = method.step(system, state, h)
        return (trunc(new.x[0, 0], n),)
    state = method.start(system, State(_obj(x), _obj(v)), h)
    new = method.step(system, state, h)
    return trunc(new.x[0, 0], n), trunc(new.v[0, 0], n)
