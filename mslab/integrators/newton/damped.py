"""Damped Newton for one implicit stage: the fallback when plain Newton fails on non-variational forces.

:func:`mslab.integrators.newton.solvers.newton_stage` calls :func:`damped_stage` only after its
plain Newton failed on forces that derive from no objective (a wind, velocity-dependent
damping), so every stage plain Newton solves keeps its result bitwise. A driven block at
``h = 0.08`` from a jostled state is such a stage: plain Newton's full steps (then halving
at most to 1/64) wander off, Newton damped from its first iteration finds the root.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.newton.solvers import _floor

if TYPE_CHECKING:
    from mslab.system import System

#: iterations of the damped Newton per iteration the method allows plain Newton
DAMPED_ITER = 4


def damped_stage(system: System, xh: np.ndarray, vh: np.ndarray, c: float, tol: float, max_iter: int,
                  policy: str, hessian: str, precision: str = "mixed") -> tuple | None:
    """Damped Newton on one stage: the point ``(X, V, a, power)`` at the root, None when it finds none.

    From ``V = v^``, each iteration takes the exact Newton direction ``du`` (the current
    Jacobian, no kept factors) and halves ``alpha`` from 1 until Armijo's condition on
    ``phi = |r|^2 / 2`` holds, ``|r(V + alpha du)|^2 <= (1 - 2 sigma alpha) |r(V)|^2``
    (``sigma = 1e-4``; ``du`` descends ``phi`` with slope ``-|r|^2``); below ``alpha = 1e-10``,
    or after ``max_iter`` iterations, it gives up. Converged as Newton: ``max |r| <= tol``
    (or the round-off floor).
    """
    from mslab.integrators.newton import linear

    solver = linear.stage_solver(system, c, policy, clamp=hessian == "clamped", precision=precision)
    solver.start_stage()

    def residual(V: np.ndarray):
        X = xh + c * V
        a, p = system.rhs(X, V)
        return V - vh - c * a, (X, V, a, p)

    V = vh.copy()
    r, point = residual(V)
    floor = 0.0
    for it in range(max_iter + 1):
        if not np.all(np.isfinite(r)):
            break
        if float(np.max(np.abs(r))) <= max(tol, floor):
            system.counters.n_iter += it
            return point
        if it == max_iter:
            break
        du = solver.direction(point, r.ravel(), exact=True).reshape(V.shape)
        floor = _floor(solver, c, point[0])
        squared, alpha = float(r.ravel() @ r.ravel()), 1.0
        while True:
            trial, trial_point = residual(V + alpha * du)
            if float(trial.ravel() @ trial.ravel()) <= (1.0 - 2e-4 * alpha) * squared:  # (False for nan)
                break
            alpha *= 0.5
            if alpha < 1e-10:
                system.counters.n_iter += it + 1
                return None
        V = V + alpha * du
        r, point = trial, trial_point
    system.counters.n_iter += it
    return None
