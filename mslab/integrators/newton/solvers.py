"""The equation solvers of the implicit Runge-Kutta family: Newton and fixed-point iteration.

Both find the stage velocities ``V_i`` of ``X_i = x_n + h sum_j A_ij V_j``,
``V_i = v_n + h sum_j A_ij a(X_j, V_j)`` (see :class:`~mslab.integrators.ImplicitRK`).

* **Newton** linearises the forces with the effects' Jacobians ``K = df/dx``,
  ``D = df/dv``. A diagonally implicit tableau is solved stage by stage
  (:func:`newton_stage`): stage ``i`` solves ``g(V) = V - v^ - h g_i a(x^ + h g_i V, V) = 0``
  (``g_i = A_ii``; ``x^, v^`` collect the earlier stages) with the matrix
  ``I - h g_i M^-1 (h g_i K + D)``, solved in its symmetric mass-scaled form on the free
  dofs with kept factorisations (:mod:`mslab.integrators.newton.linear`). When the forces derive
  from implicit Euler's objective, a line search on that objective globalises Newton (an
  undamped cloth at dt = 1/30 converges); otherwise full Newton steps first (stiff springs
  need them), then after ``full_steps`` iterations a backtracking line search halves the
  step until the residual falls (a contact switching on and off makes the iterates cycle
  otherwise); when that fails, a damped Newton (Armijo on ``|r|^2`` from the first iteration,
  :mod:`mslab.integrators.newton.damped`) tries again. A full tableau couples all stages in
  one system with blocks
  ``delta_ik I - h sum_j A_ij M^-1 (h K_j A_jk + D_j delta_jk)``, factored afresh per
  iteration (dense LAPACK, or SuperLU above ``DENSE_MAX`` unknowns;
  :mod:`mslab.integrators.newton.coupled`).
* **Fixed point** iterates ``Y <- y_n + h A F(Y)`` from ``Y = y_n``; a contraction only
  while ``h L |A| < 1``. Growing iterates stop the step with a message naming Newton.

Counted: ``n_force`` (every residual), ``n_jac`` (every Jacobian), ``n_solve`` (every
Newton direction), ``n_factor`` (every factorisation), ``n_lin_iter`` (every conjugate
gradient iteration), ``n_iter`` (every iteration).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from mslab.errors import StepFailure

if TYPE_CHECKING:

    from mslab.integrators.newton.linear import StageSolver
    from mslab.state import State
    from mslab.system import System


class ImplicitRK(Protocol):
    """What the stage solvers read of an implicit Runge-Kutta method.

    :class:`mslab.integrators.runge_kutta.ImplicitRK` implements it (and calls this module),
    so this module does not import it back. Optional attributes read with ``getattr``:
    ``linear_solver`` (default ``"auto"``), ``linearised`` (default False).
    """

    A: np.ndarray
    diagonally_implicit: bool
    max_iter: int
    rtol: float


#: shifted (minimising) steps that each lower the residual by less than 10 % before Newton's own
#: step of the indefinite matrix is tried (a root that is a saddle of the objective). The try
#: factors the indefinite matrix by SuperLU (0.3 s at 70 x 70, ten CHOLMOD factorisations): with
#: 3 it was tried, mostly in vain, 3 times in 6 buckling steps of that cloth at dt 1/30 (+35 %
#: time), with 10 once (+5 %); a 40 x 40 cloth stuck at a saddle crawled for 190 steps.
STALLED = 10


def _scale(*arrays: np.ndarray) -> float:
    return 1.0 + max(float(np.max(np.abs(a))) if a.size else 0.0 for a in arrays)


def _backtrack(residual: Callable, u: np.ndarray, du: np.ndarray, r: np.ndarray,
               full_steps: bool) -> tuple[float, np.ndarray, tuple]:
    """Halve the Newton step until the residual's norm falls (at most to 1/64 of it).

    During the first ``full_steps`` iterations the full step is taken: stiff springs need
    them (the residual may grow before it falls quadratically); after that the iterates
    may be cycling around a kink of the force (a contact switching on and off).
    Returns ``(alpha, residual, point)`` at ``u + alpha du``.
    """
    norm = float(np.linalg.norm(r))
    alpha = 1.0
    while True:
        trial, trial_point = residual(u + alpha * du)
        if (full_steps or alpha <= 1.0 / 64 or not np.isfinite(norm)
                or float(np.linalg.norm(trial)) < norm):
            return alpha, trial, trial_point
        alpha *= 0.5


def newton_stages(method: ImplicitRK, system: System, state: State,
                  dt: float) -> tuple[list[np.ndarray], list[np.ndarray], list[float]]:
    """Stage velocities, accelerations and powers of an implicit tableau by Newton's method."""
    if method.diagonally_implicit:
        return _newton_dirk(method, system, state, dt)
    from mslab.integrators.newton.coupled import newton_coupled

    return newton_coupled(method, system, state, dt)


def _newton_dirk(method: ImplicitRK, system: System, state: State, dt: float):
    A = method.A
    vs, accs, powers = [], [], []
    tol0 = method.rtol * _scale(state.v)
    for i in range(A.shape[0]):
        xh = state.x + dt * sum((A[i, j] * vs[j] for j in range(i) if A[i, j] != 0.0), np.zeros_like(state.x))
        vh = state.v + dt * sum((A[i, j] * accs[j] for j in range(i) if A[i, j] != 0.0),
                                np.zeros_like(state.v))
        g = A[i, i]
        if g == 0.0:  # an explicit stage (first stage of an ESDIRK method)
            a, p = system.rhs(xh, vh)
            vs.append(vh)
            accs.append(a)
            powers.append(p)
            continue
        X, V, a, p = newton_stage(system, xh, vh, dt * g, tol0, method.max_iter,
                                  policy=getattr(method, "linear_solver", "auto"),
                                  linearised=getattr(method, "linearised", False),
                                  hessian=getattr(method, "newton_hessian", "exact"),
                                  precision=getattr(method, "factor_precision", "mixed"))
        vs.append(V)
        accs.append(a)
        powers.append(p)
    return vs, accs, powers


def newton_stage(system: System, xh: np.ndarray, vh: np.ndarray, c: float, tol: float, max_iter: int,
                 policy: str = "auto", linearised: bool = False, full_steps: int = 4,
                 hessian: str = "exact",
                 precision: str = "mixed") -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Solve one implicit Euler-like stage ``V - v^ - c a(x^ + c V, V) = 0`` by Newton's method.

    :func:`_plain_stage` first (below). When it fails on forces that derive from no objective
    (a wind, a velocity-dependent damper: the residual backtracking of :func:`_backtrack` is
    its only globalisation), a damped Newton (:mod:`mslab.integrators.newton.damped`) starts
    again from ``V = v^``: exact directions and Armijo's backtracking on ``|r|^2`` from the first
    iteration. It runs only after a failure, so every stage plain Newton solves is solved
    exactly as before (bitwise); its work is counted on top of the failed attempt's.
    Returns ``(X, V, a, power)``; raises the first attempt's StepFailure when both fail.
    """
    try:
        return _plain_stage(system, xh, vh, c, tol, max_iter, policy, linearised, full_steps, hessian,
                            precision)
    except StepFailure:
        if linearised or variational(system):
            raise
        from mslab.integrators.newton.damped import DAMPED_ITER, damped_stage

        point = damped_stage(system, xh, vh, c, tol, DAMPED_ITER * max_iter, policy, hessian, precision)
        if point is None:
            raise
        return point


def _plain_stage(system: System, xh: np.ndarray, vh: np.ndarray, c: float, tol: float, max_iter: int,
                 policy: str, linearised: bool, full_steps: int, hessian: str,
                 precision: str = "mixed") -> tuple:
    """Solve one stage by Newton's method with the globalisation described here.

    Directions from :class:`mslab.integrators.newton.linear.StageSolver` (factorisations kept
    under ``policy``). Globalisation (:func:`_search`): when the forces derive from implicit
    Euler's objective (:func:`objective`) an Armijo line search on it (a shifted definite
    matrix when Newton's direction does not descend); otherwise full steps for ``full_steps``
    iterations, then backtracking on the residual.
    ``linearised``: one Newton step from ``V = v^`` and no convergence test (Baraff-Witkin).
    ``hessian``, ``precision``: ``ImplicitRK``'s ``newton_hessian`` and ``factor_precision``. After
    :data:`STALLED` crawling shifted steps, Newton's own step of the indefinite matrix (a saddle
    root). CG on kept factors solves to ``min(cg_rtol_max, 0.9 (|r_k| / |r_k-1|)^2)``.

    Returns ``(X, V, a, power)`` at the solution; raises StepFailure saying why it failed.
    """
    from mslab.integrators.newton import linear

    counters = system.counters
    if hessian not in ("exact", "clamped"):
        raise ValueError(f"newton_hessian must be 'exact' or 'clamped', got {hessian!r}")
    solver = linear.stage_solver(system, c, policy, clamp=hessian == "clamped", precision=precision)
    var = variational(system)

    def residual(V: np.ndarray):
        X = xh + c * V
        a, p = system.rhs(X, V)
        return V - vh - c * a, (X, V, a, p)

    def phi(V: np.ndarray):
        return objective(system, xh, vh, c, V)

    # modified Newton converges linearly: more (cheap) iterations; the line search makes progress
    # every iteration, buckling springs need tens of them
    max_iter *= (2 if solver.reuse else 1) * (4 if var else 1)
    solver.start_stage()
    V = vh.copy()
    r, point = residual(V)
    value = phi(V) if var and not linearised else 0.0
    floor, why, previous, stalled = 0.0, "", np.inf, 0
    for it in range(1, max_iter + 1):
        rnorm = float(np.max(np.abs(r))) if r.size else 0.0
        if not np.isfinite(rnorm):
            why = "the residual became non-finite"
            break
        if rnorm <= max(tol, floor):
            counters.n_iter += it - 1
            return point
        decades = float(np.log10(rnorm / max(tol, floor))) + 1.0
        forcing = solver.cg_rtol_max if previous == np.inf else min(solver.cg_rtol_max,
                                                                    0.9 * (rnorm / previous) ** 2)
        previous = rnorm
        du = solver.direction(point, r.ravel(), exact=linearised, decades=decades,
                              definite_only=var and not linearised, rtol=forcing)
        plain = du is None and stalled >= STALLED  # (None: CHOLMOD found A not positive definite)
        du = (du if du is not None else solver.indefinite_direction(r.ravel()) if plain
              else solver.shifted_direction(r.ravel())).reshape(V.shape)
        floor = _floor(solver, c, point[0])
        if linearised:
            counters.n_iter += 1
            return residual(V + du)[1]
        try:
            alpha, du, trial, trial_point, value = _search(solver, residual, phi if var else None, point, V,
                                                           r, du, value, it <= full_steps, plain)
        except StepFailure as failure:
            counters.n_iter += it
            raise StepFailure(f"Newton's line search found no decrease of implicit Euler's objective at "
                              f"iteration {it} (residual {rnorm:.2e}, tolerance {max(tol, floor):.2e}); "
                              f"try a smaller dt") from failure
        tnorm = float(np.max(np.abs(trial)))
        crawled = solver.last == "shifted" and tnorm > 0.9 * rnorm
        stalled = (STALLED if tnorm <= 0.5 * rnorm else 0) if plain else (stalled + 1 if crawled else 0)
        solver.contracted(tnorm / rnorm if alpha == 1.0 and rnorm > 0 else np.inf)
        V = V + alpha * du
        r, point = trial, trial_point
        why = f"the residual is still {tnorm:.2e}"
    counters.n_iter += it
    raise StepFailure(f"Newton iteration did not converge in {max_iter} iterations: {why} "
                      f"(tolerance {max(tol, floor):.2e}); try a smaller dt")


def _floor(solver: StageSolver, c: float, X: np.ndarray) -> float:
    """Return the residual round-off leaves at positions ``X``: ``8 eps`` times the matrix's row sum."""
    return 8.0 * np.finfo(float).eps * solver.row_sum / c * _scale(X) if solver.row_sum else 0.0


def _search(solver: StageSolver, residual: Callable, phi: Callable | None, point: tuple, V: np.ndarray,
            r: np.ndarray, du: np.ndarray, value: float, full_steps: bool, plain: bool = False) -> tuple:
    """Return ``(alpha, du, residual, point, objective)`` at the accepted step ``V + alpha du``.

    With the objective ``phi``: a descent direction (:func:`_descent`, which may replace
    ``du``) and Armijo's backtracking on ``phi``; without: :func:`_backtrack` on the
    residual (``value`` returned unchanged). ``plain``: ``du`` is Newton's own direction
    for an indefinite matrix, taken whole when it halves the residual (the objective may
    rise: the root is a saddle of it), else replaced by the shifted direction.
    """
    if phi is None:
        alpha, trial, trial_point = _backtrack(residual, V, du, r, full_steps=full_steps)
        return alpha, du, trial, trial_point, value
    rnorm = float(np.max(np.abs(r)))
    if plain:
        trial, trial_point = residual(V + du)
        if float(np.max(np.abs(trial))) <= 0.5 * rnorm:  # (False for a non-finite residual)
            return 1.0, du, trial, trial_point, phi(V + du)
        du = solver.shifted_direction(r.ravel()).reshape(du.shape)
    du, slope = _descent(solver, point, r, du)
    alpha, trial, trial_point, value = _armijo(residual, phi, V, du, value, slope, rnorm)
    return alpha, du, trial, trial_point, value


def _descent(solver: StageSolver, point: tuple, r: np.ndarray,
             du: np.ndarray) -> tuple[np.ndarray, float]:
    """Return a direction along which implicit Euler's objective descends, and its slope there.

    The Newton direction ``du`` when it descends; else the exact (not reused) factor's
    direction; else a shifted positive definite matrix's (an indefinite Newton matrix: a
    buckling spring), which always descends.
    """
    grad = -solver.rhs(r.ravel())
    slope = float(grad @ du.ravel()[solver.free])
    if not slope < 0.0 and solver.last == "modified":
        exact = solver.direction(point, r.ravel(), exact=True, definite_only=True)
        du = (solver.shifted_direction(r.ravel()) if exact is None else exact).reshape(du.shape)
        slope = float(grad @ du.ravel()[solver.free])
    if not slope < 0.0:  # indefinite Newton matrix: its direction climbs the objective
        du = solver.shifted_direction(r.ravel()).reshape(du.shape)
        slope = float(grad @ du.ravel()[solver.free])
    return du, slope


def _armijo(residual: Callable, phi: Callable, V: np.ndarray, du: np.ndarray, value: float, slope: float,
            rnorm: float) -> tuple[float, np.ndarray, tuple, float]:
    """Backtrack ``V + alpha du`` (alpha = 1, 1/2, ...) to Armijo's decrease of the objective ``phi``.

    Returns ``(alpha, residual, point, phi)`` at the accepted step; StepFailure below
    ``alpha = 1e-10``. Near the solution the objective's change drowns in round-off: a step
    that halves the residual is accepted there.
    """
    alpha = 1.0
    while True:
        trial, trial_point = residual(V + alpha * du)
        trial_value = phi(V + alpha * du)
        tnorm = float(np.max(np.abs(trial)))
        armijo = trial_value <= value + 1e-4 * alpha * slope
        flat = abs(trial_value - value) <= 1e-12 * (abs(value) + 1.0) and tnorm <= 0.5 * rnorm
        if np.isfinite(tnorm) and (armijo or flat):
            return alpha, trial, trial_point, trial_value
        alpha *= 0.5
        if alpha < 1e-10:
            raise StepFailure("no decrease")


def variational(system: System) -> bool:
    """Tell whether the forces derive from the objective :func:`objective`.

    True for conservative position-only effects plus linear drag (``f = -gamma v``, ``D``
    constant and symmetric).
    """
    for e in system.effects:
        if e.linear_drag() is not None:
            continue
        if e.velocity_dependent or e.dissipative or not e.conservative:
            return False
    return True


def objective(system: System, xh: np.ndarray, vh: np.ndarray, c: float, V: np.ndarray) -> float:
    """Return implicit Euler's objective of one stage, whose gradient is ``M r``.

    ::

        Phi(V) = 1/2 (V - v^)^T M (V - v^) + U(x^ + c V) + c/2 gamma |V|^2

    (kinetic term over free particles; ``U`` the potential energy, the drag term the
    Rayleigh function of linear drag). The stage solution minimises it.
    """
    dv = V - vh
    kin = 0.5 * float(np.sum(system.mass[~system.pinned, None] * dv[~system.pinned] ** 2))
    drag = sum(0.5 * c * e.power(xh, V) for e in system.effects if e.linear_drag() is not None)
    return kin + system.potential_energy(xh + c * V) + drag


def fixed_point_stages(method: ImplicitRK, system: System, state: State,
                       dt: float) -> tuple[list[np.ndarray], list[np.ndarray], list[float]]:
    """Stage velocities, accelerations and powers by the iteration ``Y <- y_n + h A F(Y)``."""
    A = method.A
    s = A.shape[0]
    x0, v0 = state.x, state.v
    X = np.repeat(x0[None], s, axis=0)
    V = np.repeat(v0[None], s, axis=0)
    tol_x, tol_v = method.rtol * _scale(x0), method.rtol * _scale(v0)
    prev, growing = np.inf, 0
    c = system.counters
    for it in range(1, method.max_iter + 1):
        evals = [system.rhs(X[i], V[i]) for i in range(s)]
        a = np.stack([e[0] for e in evals])
        X_next = x0[None] + dt * np.einsum("ij,jnd->ind", A, V)
        V_next = v0[None] + dt * np.einsum("ij,jnd->ind", A, a)
        change = max(float(np.max(np.abs(X_next - X))) / tol_x, float(np.max(np.abs(V_next - V))) / tol_v)
        X, V = X_next, V_next
        if change <= 1.0:
            c.n_iter += it
            return list(V), list(a), [e[1] for e in evals]
        growing = growing + 1 if change > prev else 0
        prev = change
        if growing >= 3 or not np.isfinite(change):
            c.n_iter += it
            raise StepFailure(
                f"fixed-point iteration diverges at dt={dt:g} (iterates grow: h*L >= 1, the map is no "
                f"contraction); use Newton's method (method 'implicit_euler') or a smaller dt")
    c.n_iter += method.max_iter
    raise StepFailure(f"fixed-point iteration did not converge in {method.max_iter} iterations at "
                      f"dt={dt:g}; use Newton's method (method 'implicit_euler') or a smaller dt")
