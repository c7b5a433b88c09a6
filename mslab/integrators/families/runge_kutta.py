"""Runge-Kutta methods, explicit and implicit, each defined by its Butcher tableau.

For ``y = (x, v)`` and ``y' = F(y) = (v, a(x, v))`` a method with ``s`` stages steps::

    Y_i = y_n + h sum_j A_ij K_j,     K_i = F(Y_i)     (i = 1..s)
    y_{n+1} = y_n + h sum_i b_i K_i

Explicit tableaux (``A`` strictly lower triangular) compute the stages one after the
other; implicit ones solve for them (:mod:`mslab.integrators.newton.solvers`). The dissipated
work is integrated with the same weights ``b_i`` from the power at each stage, so the
energy ledger is as accurate as the method. The stability function
``R(z) = det(I - zA + z 1 b^T) / det(I - zA)`` (:mod:`mslab.integrators.families.polynomials`) and
the oscillator map ``R(dt J)`` are computed from the very coefficients that step.
"""

from __future__ import annotations

from collections.abc import Iterable
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from mslab.integrators.base import Integrator
from mslab.integrators.families.coefficients import as_given, frozen
from mslab.integrators.families.polynomials import TableauPolynomials, exact_polynomials
from mslab.state import State

if TYPE_CHECKING:
    from mslab.system import System


class _RungeKutta(Integrator):
    """What explicit and implicit tableaux share: coefficients, R(z), the oscillator map."""

    def __init__(self, A: Iterable[Iterable[Any]], b: Iterable[Any], c: Iterable[Any] | None = None,
                 name: str = "runge_kutta", order: int = 0, doc: str | None = None):
        self.coefficients = {"A": as_given(A), "b": as_given(b), "c": None if c is None else as_given(c)}
        self.A = frozen(A, 2)
        self.b = frozen(b, 1)
        s = self.b.shape[0]
        self.c = frozen(self.A.sum(axis=1) if c is None else c, 1)
        if self.A.shape != (s, s) or self.c.shape != (s,):
            raise ValueError(f"Butcher tableau: A must be ({s}, {s}) and c of length {s} like b, "
                             f"got A {self.A.shape}, c {self.c.shape}")
        self.name = name
        self.order = int(order)
        self.n_stages = s
        if doc:
            self.__doc__ = doc

    @cached_property
    def polynomials(self) -> TableauPolynomials:
        """``N``, ``D`` of ``R = N/D`` from the coefficients as given, exact (computed once per tableau)."""
        return exact_polynomials(self.coefficients["A"], self.coefficients["b"])

    def stability_function(self, z: np.ndarray) -> np.ndarray:
        """``R(z) = det(I - zA + z 1 b^T) / det(I - zA)``; inf at a pole (explicit: a polynomial).

        Evaluated from :attr:`polynomials` (each coefficient rounded once to a float).
        """
        z = np.asarray(z, dtype=complex)
        p = self.polynomials
        num = np.polynomial.polynomial.polyval(z, p.N_float)
        if len(p.D) == 1:  # explicit: D = 1
            return num
        den = np.polynomial.polynomial.polyval(z, p.D_float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(den == 0, np.inf, num / np.where(den == 0, 1.0, den))

    def oscillator_matrix(self, h_omega: np.ndarray, h_gamma: np.ndarray) -> np.ndarray:
        """``R(dt J)`` with ``dt J = [[0, 1], [-h_omega^2, -h_gamma]]`` on the state ``(x, dt v)``."""
        w2, g = np.broadcast_arrays(np.square(np.asarray(h_omega, dtype=float)),
                                    np.asarray(h_gamma, dtype=float))
        shape = w2.shape
        w2, g = w2.ravel(), g.ravel()
        n, s = w2.size, self.b.size
        Z = np.zeros((n, 2, 2))
        Z[:, 0, 1] = 1.0
        Z[:, 1, 0] = -w2
        Z[:, 1, 1] = -g
        # stages K = (I - A kron Z)^-1 (1 kron Z) y,  y' = (I + (b^T kron Z) K) y
        big = np.eye(2 * s)[None] - np.einsum("ij,nab->niajb", self.A, Z).reshape(n, 2 * s, 2 * s)
        rhs = np.einsum("i,nab->niab", np.ones(s), Z).reshape(n, 2 * s, 2)
        with np.errstate(all="ignore"):
            try:
                K = np.linalg.solve(big, rhs).reshape(n, s, 2, 2)
            except np.linalg.LinAlgError:  # a pole of R on this grid: solve point by point
                K = np.stack([_solve_or_inf(B, r) for B, r in zip(big, rhs, strict=True)]).reshape(n, s, 2, 2)
        M = np.eye(2)[None] + np.einsum("i,niab->nab", self.b, K)
        return M.reshape(shape + (2, 2))

    def _combine(self, state: State, vs: list, accs: list, powers: list, dt: float) -> State:
        """``y_{n+1} = y_n + h sum_i b_i K_i`` from the stage velocities, accelerations and powers."""
        x_new, v_new, work = state.x, state.v, 0.0
        for i, bi in enumerate(self.b):
            if bi != 0.0:
                x_new = x_new + (dt * bi) * vs[i]
                v_new = v_new + (dt * bi) * accs[i]
                work += dt * bi * powers[i]
        return State(x_new, v_new, (), state.dissipated + work)


def _solve_or_inf(B: np.ndarray, r: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(B, r)
    except np.linalg.LinAlgError:
        return np.full_like(r, np.inf)


class ExplicitRK(_RungeKutta):
    """Explicit Runge-Kutta method from a Butcher tableau.

    ``Y_i = y_n + h sum_{j<i} A_ij K_j``, ``K_i = F(Y_i)``, ``y_{n+1} = y_n + h sum_i b_i K_i``.

    Cost: ``s`` force evaluations per step. Stability function
    ``R(z) = 1 + z b^T (I - z A)^-1 1``, a polynomial of degree ``s``.

    Parameters
    ----------
    A : array_like, shape (s, s), strictly lower triangular
    b : array_like, shape (s,)
    c : array_like, shape (s,), optional (default: row sums of A)
        Coefficients may be floats, ints, ``Fraction``, sympy numbers or strings such as
        ``"19372/6561"``; :mod:`mslab.derive` reads them as given (exact ones stay exact).
    name : str
    order : int
    doc : str, optional
        The method's docstring (update equations, order, cost).
    """

    family = "explicit_rk"
    explicit = True

    def __init__(self, A: Iterable[Iterable[Any]], b: Iterable[Any], c: Iterable[Any] | None = None,
                 name: str = "explicit_rk", order: int = 0, doc: str | None = None):
        super().__init__(A, b, c, name, order, doc)
        if np.any(np.triu(self.A) != 0.0):
            raise ValueError("Butcher tableau of an explicit method: A must be strictly lower triangular")
        s = self.n_stages
        # non-zero coefficients only: rk4 combines at most one earlier stage per stage
        self._rows = [[(j, self.A[i, j]) for j in range(i) if self.A[i, j] != 0.0] for i in range(s)]

    @property
    def compiled(self) -> tuple[str, tuple]:
        """The generic compiled Runge-Kutta loop over ``A, b``."""
        return "explicit_rk", (self.A, self.b)

    def stages(self, system: System, x: np.ndarray, v: np.ndarray, h: float, first: tuple | None = None,
               hold_x: bool = False) -> tuple[list, list, list]:
        """Run the explicit stage loop: ``Y_i = y_n + h sum_{j<i} A_ij K_j``, ``K_i = F(Y_i)``, in order.

        Return the stage velocities, accelerations and powers. ``first``: ``(a, p)`` of the
        first stage when already evaluated at ``(x, v)``. ``hold_x``: integrate ``v' = a(x, v)``
        with ``x`` held fixed (a splitting's kick with velocity-dependent forces).
        """
        vs: list[np.ndarray] = []
        accs: list[np.ndarray] = []
        powers: list[float] = []
        for i, row in enumerate(self._rows):
            xi, vi = x, v
            for j, aij in row:
                if not hold_x:
                    xi = xi + (h * aij) * vs[j]
                vi = vi + (h * aij) * accs[j]
            a, p = first if i == 0 and first is not None else system.rhs(xi, vi)
            vs.append(vi)
            accs.append(a)
            powers.append(p)
        return vs, accs, powers

    def step(self, system: System, state: State, dt: float) -> State:
        """One step: ``s`` counted force evaluations."""
        return self._combine(state, *self.stages(system, state.x, state.v, dt), dt)


class ImplicitRK(_RungeKutta):
    """Implicit (or diagonally implicit) Runge-Kutta method from a Butcher tableau.

    The stages are unknown: with ``V_i`` the stage velocities,
    ``X_i = x_n + h sum_j A_ij V_j`` and ``V_i = v_n + h sum_j A_ij a(X_j, V_j)``;
    then ``x_{n+1} = x_n + h sum_i b_i V_i``, ``v_{n+1} = v_n + h sum_i b_i a(X_i, V_i)``.

    ``solver="newton"`` (default) solves for the ``V_i`` by Newton's method with the
    effects' Jacobians (:func:`mslab.integrators.newton.solvers.newton_stages`): stage by stage
    when ``A`` is lower triangular (DIRK), all stages at once otherwise.
    ``solver="fixed_point"`` iterates ``Y <- y_n + h A F(Y)``, which needs only force
    evaluations but converges only while ``h L |A| < 1``. ``solver="linearised"`` takes one
    Newton step per stage from ``V = v^`` and stops there (Baraff and Witkin's linearised
    implicit Euler): exact on linear forces, an ``O(h^2)`` local deviation otherwise.
    ``linear_solver`` chooses how Newton's linear systems are solved
    (:mod:`mslab.integrators.newton.linear`): ``"auto"`` keeps and reuses factorisations above
    300 unknowns, ``"reuse"`` always, ``"fresh"`` factors every Newton matrix.
    ``newton_hessian="clamped"`` (compiled path, ``backend="numba"``) drops each compressed
    spring's negative term from Newton's matrix (Choi & Ko 2002): always positive definite,
    the same solution (the residual stays exact), but linear convergence where springs are
    compressed: measured 2.4-2.5x slower than ``"exact"`` on a 70x70 cloth at dt = 1/60, and it
    did not converge in 4 of 6 steps at dt = 1/30 (``benchmarks/RESULTS.md``).
    ``factor_precision="mixed"`` (default) factors Newton matrices of more than 10 000 unknowns
    in float32 and solves in float64 by CG preconditioned with those factors, ``"double"``
    factors in float64 (:mod:`mslab.integrators.newton.mixed`); the same roots to Newton's
    tolerance.

    Cost per step: Newton — per iteration one force evaluation, one Jacobian and one linear
    solve per stage, plus the evaluations of the residual; fixed point — ``s`` evaluations
    per iteration. Counted in ``n_force, n_jac, n_solve, n_iter``, and ``n_factor``,
    ``n_lin_iter`` (factorisations kept and reused, conjugate gradient iterations).

    Parameters
    ----------
    A : array_like, shape (s, s)
    b, c : array_like, shape (s,)
    name : str
    order : int
    solver : {"newton", "fixed_point", "linearised"}
    linear_solver : {"auto", "fresh", "reuse"}
    newton_hessian : {"exact", "clamped"}
    factor_precision : {"mixed", "double"}
    a_stable : bool, optional
        Declared A-stability (tested against ``R(z)``); default: measured on a grid.
    doc : str, optional
    """

    family = "implicit_rk"
    explicit = False
    rtol: float = 1e-10
    max_iter: int = 25

    def __init__(self, A: Iterable[Iterable[Any]], b: Iterable[Any], c: Iterable[Any] | None = None,
                 name: str = "implicit_rk", order: int = 0, solver: str = "newton",
                 symplectic: bool = False, doc: str | None = None, linear_solver: str = "auto",
                 newton_hessian: str = "exact", factor_precision: str = "mixed"):
        super().__init__(A, b, c, name, order, doc)
        if solver not in ("newton", "fixed_point", "linearised"):
            raise ValueError(f"solver must be 'newton', 'fixed_point' or 'linearised', got {solver!r}")
        from mslab.integrators.newton.linear import POLICIES, PRECISIONS

        if linear_solver not in POLICIES:
            raise ValueError(f"linear_solver must be one of {POLICIES}, got {linear_solver!r}")
        if newton_hessian not in ("exact", "clamped"):
            raise ValueError(f"newton_hessian must be 'exact' or 'clamped', got {newton_hessian!r}")
        if factor_precision not in PRECISIONS:
            raise ValueError(f"factor_precision must be one of {PRECISIONS}, got {factor_precision!r}")
        self.newton_hessian = newton_hessian
        self.factor_precision = factor_precision
        self.solver = solver
        self.linear_solver = linear_solver
        self.linearised = solver == "linearised"
        self.symplectic = symplectic
        self.diagonally_implicit = not np.any(np.triu(self.A, 1))
        #: ``b`` is the last row of ``A``: the new state is the last stage
        self.stiffly_accurate = bool(np.array_equal(self.b, self.A[-1]))
        if self.linearised and not self.diagonally_implicit:
            raise ValueError("solver 'linearised' (one Newton step per stage) needs a diagonally "
                             "implicit tableau")
        if newton_hessian == "clamped" and (solver == "fixed_point" or not self.diagonally_implicit):
            raise ValueError("newton_hessian='clamped' needs Newton's method (solver 'newton' or "
                             "'linearised') on a diagonally implicit tableau")
        if solver == "fixed_point":
            self.max_iter = 200
        self.a_stable = solver != "fixed_point" and self._a_stable()

    @property
    def compiled_only(self) -> bool:
        """Whether the method steps only on the compiled path (the clamped matrix is built there)."""
        return self.newton_hessian == "clamped"

    def start(self, system: System, state: State, dt: float) -> State:
        """Start a run: forget the factorisations an earlier run kept on ``system``.

        A run's Newton iterations, counts and round-off then depend on the run alone.
        """
        from mslab.integrators.newton import linear

        linear.forget(system)
        return state

    def _a_stable(self) -> bool:
        """``|R(iy)| <= 1`` on the imaginary axis, no pole in the left half plane, ``|R(-inf)| <= 1``."""
        y = np.concatenate([[0.0], np.geomspace(1e-3, 1e6, 400)])
        on_axis = np.abs(self.stability_function(1j * y))
        theta = np.linspace(0.5 * np.pi, 1.5 * np.pi, 181)
        left = np.abs(self.stability_function(np.outer(np.geomspace(1e-2, 1e6, 60), np.exp(1j * theta))))
        return bool(np.all(on_axis <= 1.0 + 1e-9) and np.all(left <= 1.0 + 1e-9))

    @property
    def compiled(self) -> tuple[str, tuple]:
        """Name the compiled path: this step over compiled forces and Jacobians (:mod:`mslab.fast.newton`)."""
        return "implicit", ()

    def step(self, system: System, state: State, dt: float) -> State:
        """One step: solve for the stages, then combine them with ``b``."""
        from mslab.integrators.newton import solvers

        if self.solver == "fixed_point":
            vs, accs, powers = solvers.fixed_point_stages(self, system, state, dt)
        else:
            vs, accs, powers = solvers.newton_stages(self, system, state, dt)
        if self.stiffly_accurate:  # the new state is the last stage
            X = state.x + dt * sum(a * v for a, v in zip(self.A[-1], vs, strict=True) if a != 0.0)
            work = dt * float(self.b @ np.asarray(powers))
            return State(X, vs[-1], (), state.dissipated + work)
        return self._combine(state, vs, accs, powers, dt)
