"""Explicit Runge-Kutta methods, each defined by its Butcher tableau.

One code path steps every tableau; the stability analysis (``mslab.stability``) and the
sympy order check (``mslab.derive``) read the very same coefficients ``A, b, c``.
"""

from __future__ import annotations

import numpy as np

from mslab.integrators.base import Integrator, register
from mslab.state import State


class ExplicitRK(Integrator):
    """Explicit Runge-Kutta method from a Butcher tableau.

    For ``y = (x, v)`` and ``y' = F(y) = (v, a(x, v))`` with ``s`` stages::

        Y_i = y_n + h sum_{j<i} A_ij K_j,     K_i = F(Y_i)     (i = 1..s)
        y_{n+1} = y_n + h sum_i b_i K_i

    The dissipated work is integrated with the same weights ``b_i`` from the power at
    each stage, so the energy ledger is as accurate as the method.

    Cost: ``s`` force evaluations per step. Stability function
    ``R(z) = 1 + z b^T (I - z A)^-1 1``.

    Parameters
    ----------
    A : array_like, shape (s, s), strictly lower triangular
    b : array_like, shape (s,)
    c : array_like, shape (s,), optional (default: row sums of A)
    name : str
    order : int
    """

    explicit = True
    symplectic = False

    def __init__(self, A, b, c=None, name: str = "explicit_rk", order: int = 0,
                 course: bool = False, doc: str | None = None):
        self.A = np.array(A, dtype=float)
        self.b = np.array(b, dtype=float)
        self.c = self.A.sum(axis=1) if c is None else np.array(c, dtype=float)
        s = self.b.shape[0]
        if self.A.shape != (s, s) or self.c.shape != (s,):
            raise ValueError("Butcher tableau: A must be (s, s), b and c of length s")
        if np.any(np.triu(self.A) != 0.0):
            raise ValueError("Butcher tableau of an explicit method: A must be strictly lower triangular")
        for coefficients in (self.A, self.b, self.c):  # the tableau that steps is the one analysed:
            coefficients.flags.writeable = False        # no later edit may make them differ
        self.name = name
        self.order = int(order)
        self.n_stages = s
        self.course = course
        if doc:
            self.__doc__ = doc
        # non-zero coefficients only: rk4 combines at most one earlier stage per stage
        self._rows = [[(j, self.A[i, j]) for j in range(i) if self.A[i, j] != 0.0] for i in range(s)]
        self._weights = [(i, self.b[i]) for i in range(s) if self.b[i] != 0.0]

    def step(self, system, state: State, dt: float) -> State:
        x, v = state.x, state.v
        kx: list[np.ndarray] = []
        kv: list[np.ndarray] = []
        power: list[float] = []
        for row in self._rows:
            xi, vi = x, v
            for j, aij in row:
                xi = xi + (dt * aij) * kx[j]
                vi = vi + (dt * aij) * kv[j]
            a, p = system.rhs(xi, vi)
            kx.append(vi)
            kv.append(a)
            power.append(p)
        x_new, v_new, work = x, v, 0.0
        for i, bi in self._weights:
            x_new = x_new + (dt * bi) * kx[i]
            v_new = v_new + (dt * bi) * kv[i]
            work += dt * bi * power[i]
        return State(x_new, v_new, (), state.dissipated + work)


euler = register(ExplicitRK(
    [[0.0]], [1.0], name="euler", order=1, course=True,
    doc="""Forward (explicit) Euler, seed eq. 6.

    ``x_{n+1} = x_n + h v_n``,  ``v_{n+1} = v_n + h a(x_n, v_n)``.

    Order 1 (Taylor series cut after the first derivative, local error O(h^2)); one force
    evaluation per step. Stability: ``R(z) = 1 + z``, stable for ``-2 < h lambda < 0`` on
    real lambda (seed eq. 32) and *never* for an undamped oscillator (|R(i w h)| > 1):
    its energy grows every step. Tableau: ``A = [[0]], b = [1]``.
    """))

heun = register(ExplicitRK(
    [[0.0, 0.0], [1.0, 0.0]], [0.5, 0.5], name="heun", order=2, course=True,
    doc="""Heun's method (explicit trapezoidal rule, improved Euler), seed eqs. 11-15.

    Predictor ``~y = y_n + h F(y_n)`` (an Euler step), then
    ``y_{n+1} = y_n + h/2 (F(y_n) + F(~y))``: the average of the slopes at both ends.

    Order 2; two force evaluations per step. ``R(z) = 1 + z + z^2/2``.
    Tableau: ``A = [[0, 0], [1, 0]], b = [1/2, 1/2]``.
    """))

midpoint = register(ExplicitRK(
    [[0.0, 0.0], [0.5, 0.0]], [0.0, 1.0], name="midpoint", order=2, course=True,
    doc="""Explicit midpoint method (modified Euler), seed section 2.5.

    Half an Euler step to ``y_{n+1/2} = y_n + h/2 F(y_n)``, then the whole step with the
    slope there: ``y_{n+1} = y_n + h F(y_{n+1/2})``.

    Order 2; two force evaluations per step. ``R(z) = 1 + z + z^2/2`` (as Heun).
    Tableau: ``A = [[0, 0], [1/2, 0]], b = [0, 1]``.
    """))

rk3 = register(ExplicitRK(
    [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [-1.0, 2.0, 0.0]], [1 / 6, 2 / 3, 1 / 6], name="rk3", order=3,
    doc="""Kutta's third-order method (beyond the course).

    ``K1 = F(y_n)``, ``K2 = F(y_n + h/2 K1)``, ``K3 = F(y_n - h K1 + 2h K2)``,
    ``y_{n+1} = y_n + h/6 (K1 + 4 K2 + K3)``.

    Order 3; three force evaluations per step. ``R(z) = 1 + z + z^2/2 + z^3/6``.
    """))

rk4 = register(ExplicitRK(
    [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
    [1 / 6, 1 / 3, 1 / 3, 1 / 6], name="rk4", order=4, course=True,
    doc="""Classical Runge-Kutta method, seed eqs. 16-20.

    ``K1 = F(y_n)``, ``K2 = F(y_n + h/2 K1)``, ``K3 = F(y_n + h/2 K2)``,
    ``K4 = F(y_n + h K3)``, ``y_{n+1} = y_n + h/6 (K1 + 2 K2 + 2 K3 + K4)``.
    (The fourth stage is at ``t + h``; seed eq. 19 writes ``t``.)

    Order 4; four force evaluations per step. ``R(z) = sum_{k<=4} z^k / k!``; real
    stability interval about [-2.785, 0], imaginary about |y| <= 2.828.
    """))
