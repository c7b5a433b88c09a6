"""Implicit methods: implicit Euler (Newton or fixed-point iteration), implicit midpoint.

Each step solves an equation for the new velocity. Newton's method linearises the forces
with the effects' Jacobians ``K = df/dx`` and ``D = df/dv`` and solves a sparse linear
system per iteration (counted: ``n_jac``, ``n_solve``, ``n_iter``); the fixed-point
iteration only needs force evaluations but converges only while ``h L < 1``
(``L`` the Lipschitz constant of the right-hand side).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from mslab.errors import StepFailure
from mslab.integrators.base import Integrator, register
from mslab.state import State


def _scale(*arrays: np.ndarray) -> float:
    return 1.0 + max(float(np.max(np.abs(a))) if a.size else 0.0 for a in arrays)


class _NewtonVelocity(Integrator):
    """Newton iteration on ``g(v') = v' - v_n - h a(X(v'), V(v')) = 0``.

    Subclasses say where the forces are evaluated (``_points``: X and V as functions of
    the unknown new velocity v', both affine) and the slopes ``dX/dv'``, ``dV/dv'``
    (``_dpoints``); the Newton matrix is ``J = I - h M^-1 (dX/dv' K + dV/dv' D)``.
    """

    explicit = False
    rtol: float = 1e-10
    max_iter: int = 25
    full_steps: int = 4  # undamped Newton iterations before the line search starts

    def _points(self, state, v_new, dt):  # -> (X, V) where forces are evaluated
        raise NotImplementedError

    def _dpoints(self, dt):  # -> (dX/dv', dV/dv') scalars
        raise NotImplementedError

    def _finish(self, state, v_new, dt, p):
        raise NotImplementedError

    def step(self, system, state, dt):
        c = system.counters
        v0 = state.v
        v_new = v0.copy()
        tol = self.rtol * _scale(v0)
        dxdv, dvdv = self._dpoints(dt)

        def residual_at(v):
            X, V = self._points(state, v, dt)
            a, p = system.rhs(X, V)
            return X, V, v - v0 - dt * a, p

        X, V, residual, p = residual_at(v_new)
        for it in range(1, self.max_iter + 1):
            if not np.all(np.isfinite(residual)):
                break
            if float(np.max(np.abs(residual))) <= tol:
                c.n_iter += it - 1
                return self._finish(state, v_new, dt, p)
            K, D = system.jacobians(X, V)
            lin = K * dxdv if D is None else K * dxdv + D * dvdv
            dv, row_sum = _newton_solve(system, lin, dt, residual.ravel())
            dv = dv.reshape(v0.shape)
            c.n_solve += 1
            # roundoff floor of the residual: stiff springs (k/m ~ 1e9) amplify the rounding
            # of positions by dt * |M^-1 K|; below that no iteration can go
            if row_sum > 0.0:
                tol = max(tol, 8.0 * np.finfo(float).eps * row_sum / dxdv * _scale(X))
            # Full Newton steps first (on stiff springs the residual may grow before it falls
            # quadratically). If that has not converged after a few iterations, the iterates
            # are cycling around a kink of the force (a contact switching on and off):
            # backtrack, halving the step until the residual decreases.
            norm = float(np.linalg.norm(residual))
            alpha = 1.0
            while True:
                X, V, trial, p = residual_at(v_new + alpha * dv)
                if (it <= self.full_steps or alpha <= 1.0 / 64 or not np.isfinite(norm)
                        or float(np.linalg.norm(trial)) < norm):
                    break
                alpha *= 0.5
            v_new = v_new + alpha * dv
            residual = trial
        c.n_iter += it
        raise StepFailure(f"Newton iteration did not converge in {self.max_iter} iterations "
                          f"(residual tolerance {tol:.2e}); try a smaller dt")


#: systems up to this many unknowns solve Newton's linear system densely (LAPACK beats
#: building scipy.sparse objects there); larger ones use a sparse direct solve
DENSE_MAX = 300


def _newton_solve(system, lin, dt: float, residual: np.ndarray) -> tuple[np.ndarray, float]:
    """Solve ``(I - dt M^-1 lin) dv = -residual``; also return ``max_i sum_j |dt M^-1 lin|_ij``."""
    minv = np.repeat(system.inv_mass, system.dim)
    if residual.size <= DENSE_MAX:
        S = (dt * minv)[:, None] * lin.toarray()
        row_sum = float(np.abs(S).sum(axis=1).max())
        S *= -1.0
        S[np.diag_indices_from(S)] += 1.0
        return np.linalg.solve(S, -residual), row_sum
    S = lin.tocsr(copy=True)
    S.data *= np.repeat(dt * minv, np.diff(S.indptr))  # row scaling by dt M^-1
    row_sum = float(abs(S).sum(axis=1).max()) if S.nnz else 0.0
    J = (sp.identity(residual.size, format="csr") - S).tocsc()
    return spla.spsolve(J, -residual), row_sum


class ImplicitEuler(_NewtonVelocity):
    """Implicit (backward) Euler solved by Newton's method, seed eq. 27.

    ``x_{n+1} = x_n + h v_{n+1}``,  ``v_{n+1} = v_n + h a(x_{n+1}, v_{n+1})``

    Newton on the velocity: ``(I - h M^-1 (h K + D)) dv = -g(v)`` with
    ``g(v) = v - v_n - h a(x_n + h v, v)``, sparse direct solve, until
    ``max|g| <= 1e-10 (1 + max|v_n|)``. One Newton iteration from ``v = v_n`` is
    Baraff-Witkin's linearised implicit Euler.

    Order 1; per iteration one force evaluation, one Jacobian, one linear solve (plus one
    first residual evaluation, and one more for each halving of a Newton step by the
    backtracking line search, which only kinks such as contacts switching on need).
    ``R(z) = 1/(1 - z)``: A-stable (and L-stable); it damps oscillations numerically, so
    energy decays even without physical damping.
    """

    name = "implicit_euler"
    order = 1
    course = True

    def _points(self, state, v_new, dt):
        return state.x + dt * v_new, v_new

    def _dpoints(self, dt):
        return dt, 1.0

    def _finish(self, state, v_new, dt, p):
        return State(state.x + dt * v_new, v_new, (), state.dissipated + dt * p)


class ImplicitMidpoint(_NewtonVelocity):
    """Implicit midpoint rule (beyond the course), solved by Newton's method.

    ``y_{n+1} = y_n + h F((y_n + y_{n+1}) / 2)``: with ``v_m = (v_n + v_{n+1})/2``,
    ``x_{n+1} = x_n + h v_m``, ``v_{n+1} = v_n + h a(x_n + h/2 v_m, v_m)``.

    Order 2; symplectic and A-stable, ``R(z) = (1 + z/2)/(1 - z/2)``, ``|R(iy)| = 1``:
    neither gains nor loses energy on an oscillator. Cost as implicit Euler.
    """

    name = "implicit_midpoint"
    order = 2
    symplectic = True

    def _points(self, state, v_new, dt):
        vm = 0.5 * (state.v + v_new)
        return state.x + (0.5 * dt) * vm, vm

    def _dpoints(self, dt):
        return 0.25 * dt, 0.5

    def _finish(self, state, v_new, dt, p):
        vm = 0.5 * (state.v + v_new)
        return State(state.x + dt * vm, v_new, (), state.dissipated + dt * p)


class ImplicitEulerFixedPoint(Integrator):
    """Implicit Euler solved by fixed-point iteration, seed eq. 28.

    ``y^{(k+1)} = y_n + h F(y^{(k)})`` with ``y = (x, v)``, started from
    ``y^{(0)} = y_n`` (the first iterate is then a forward Euler step), until the change
    between iterates is below ``1e-10`` relative to the state's size.

    The iteration is a contraction only while ``h L < 1`` (for a spring of frequency
    w: roughly ``h w < 1``). When the iterates grow instead, the step fails with a message
    suggesting Newton's method (``implicit_euler``) or a smaller dt.

    Order 1; one force evaluation per iteration; same ``R(z) = 1/(1 - z)`` as Newton
    when it converges.
    """

    name = "implicit_euler_fp"
    order = 1
    explicit = False
    course = True
    rtol: float = 1e-10
    max_iter: int = 200

    def step(self, system, state, dt):
        x0, v0 = state.x, state.v
        x, v = x0, v0
        tol_x, tol_v = self.rtol * _scale(x0), self.rtol * _scale(v0)
        prev = np.inf
        growing = 0
        for it in range(1, self.max_iter + 1):
            a, p = system.rhs(x, v)
            x_next = x0 + dt * v
            v_next = v0 + dt * a
            change = max(float(np.max(np.abs(x_next - x))) / tol_x,
                         float(np.max(np.abs(v_next - v))) / tol_v)
            x, v = x_next, v_next
            if change <= 1.0:
                system.counters.n_iter += it
                return State(x, v, (), state.dissipated + dt * p)
            growing = growing + 1 if change > prev else 0
            prev = change
            if growing >= 3 or not np.isfinite(change):
                system.counters.n_iter += it
                raise StepFailure(
                    f"fixed-point iteration diverges at dt={dt:g} (iterates grow: h*L >= 1, the "
                    f"map is no contraction); use Newton's method (method 'implicit_euler') or a "
                    f"smaller dt")
        system.counters.n_iter += self.max_iter
        raise StepFailure(f"fixed-point iteration did not converge in {self.max_iter} iterations at "
                          f"dt={dt:g}; use Newton's method (method 'implicit_euler') or a smaller dt")


implicit_euler = register(ImplicitEuler())
implicit_midpoint = register(ImplicitMidpoint())
implicit_euler_fp = register(ImplicitEulerFixedPoint())
