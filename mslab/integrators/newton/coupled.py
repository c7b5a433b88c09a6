"""Newton's method for a fully implicit tableau: all stages coupled in one system.

A full tableau (Gauss-Legendre, Radau IIA, ...) couples its ``s`` stages: Newton's matrix has
blocks ``delta_ik I - h sum_j A_ij M^-1 (h K_j A_jk + D_j delta_jk)`` over all stages,
assembled and factored afresh per iteration: up to
:data:`~mslab.integrators.newton.factor.DENSE_MAX` unknowns as dense arrays and dense LAPACK
(:func:`_dense_coupling`), above that in scipy.sparse and SuperLU. Diagonally
implicit tableaux are solved stage by stage instead (:mod:`mslab.integrators.newton.solvers`).
Counted as there: ``n_force``, ``n_jac``, ``n_solve``, ``n_factor``, ``n_iter``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from mslab.errors import StepFailure
from mslab.integrators.newton import factor
from mslab.integrators.newton.solvers import _backtrack, _scale

if TYPE_CHECKING:
    import scipy.sparse as sp

    from mslab.integrators.newton.solvers import ImplicitRK
    from mslab.state import State
    from mslab.system import System


def _newton(system: System, u0: np.ndarray, residual: Callable, solve: Callable, tol: float, max_iter: int,
            full_steps: int):
    """Newton's iteration ``u <- u + alpha du`` with ``J du = -r``.

    ``residual(u) -> (r, point)``; ``solve(point, r) -> (du, floor)`` assembles and solves
    the linear system at ``point`` and returns a round-off floor for the tolerance.
    Returns ``(u, point)`` at convergence; raises StepFailure otherwise.
    """
    c = system.counters
    u = u0
    r, point = residual(u)
    for it in range(1, max_iter + 1):
        if not np.all(np.isfinite(r)):
            break
        if float(np.max(np.abs(r))) <= tol:
            c.n_iter += it - 1
            return u, point
        du, floor = solve(point, r)
        c.n_solve += 1
        tol = max(tol, floor)
        alpha, trial, trial_point = _backtrack(residual, u, du, r, full_steps=it <= full_steps)
        u = u + alpha * du
        r, point = trial, trial_point
    c.n_iter += it
    raise StepFailure(f"Newton iteration did not converge in {max_iter} iterations "
                      f"(residual tolerance {tol:.2e}); try a smaller dt")


def _linear_solve(S: sp.spmatrix | np.ndarray, residual: np.ndarray) -> tuple[np.ndarray, float]:
    """Solve ``(I - S) du = -residual`` (S sparse or dense); also return ``max_i sum_j |S_ij|``."""
    if residual.size <= factor.DENSE_MAX:
        S = S if isinstance(S, np.ndarray) else S.toarray()
        row_sum = float(np.abs(S).sum(axis=1).max()) if S.size else 0.0
        J = -S
        J[np.diag_indices_from(J)] += 1.0
        return np.linalg.solve(J, -residual), row_sum
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    S = S.tocsr()
    row_sum = float(abs(S).sum(axis=1).max()) if S.nnz else 0.0
    J = (sp.identity(residual.size, format="csr") - S).tocsc()
    return spla.spsolve(J, -residual), row_sum


def _dense_coupling(system: System, A: np.ndarray, X: np.ndarray, V: np.ndarray, dt: float) -> np.ndarray:
    """``S`` of :func:`_linear_solve` as a dense array, for systems of at most ``DENSE_MAX`` unknowns.

    Block ``(i, k)``: ``h^2 sum_j (A_ij M^-1 K_j) A_jk + h A_ik M^-1 D_k``, the terms of the
    sparse products in the same operations (a zero entry of ``A`` adds no term), so for two
    stages the matrix is bitwise the sparse one (with three or more, the sums over ``j`` may
    be added in another order), without the dozens of small scipy.sparse objects an iteration
    of the sparse assembly builds (``benchmarks/small_runs.py``: a run of gauss2 or radau_iia2
    on an 8-particle chain in about a third of the time). Cost ``O(s^3 n^2)``, ``n`` = dofs.
    """
    s = A.shape[0]
    n = X[0].size
    minv = np.repeat(system.inv_mass, system.dim)[:, None]
    MK, MD = [], []
    for i in range(s):  # the effects' terms summed as System.jacobians sums them, in dense arrays
        stiff, damp = system.jacobian_terms(X[i], V[i])
        K = sum((t.toarray() for t in stiff[1:]), stiff[0].toarray()) if stiff else np.zeros((n, n))
        MK.append(minv * K)
        MD.append(minv * sum((t.toarray() for t in damp[1:]), damp[0].toarray()) if damp else None)
    S = np.zeros((s * n, s * n))
    for i in range(s):
        for k in range(s):
            block = np.zeros((n, n))
            for j in range(s):
                if A[i, j] != 0.0 and A[j, k] != 0.0:
                    block = block + (A[i, j] * MK[j]) * A[j, k]
            block = dt * dt * block
            if MD[k] is not None and A[i, k] != 0.0:
                block = block + dt * (A[i, k] * MD[k])
            S[i * n:(i + 1) * n, k * n:(k + 1) * n] = block
    return S


def _sparse_coupling(system: System, A: np.ndarray, X: np.ndarray, V: np.ndarray, dt: float) -> sp.csr_matrix:
    """``S`` of :func:`_linear_solve` (block ``(i, k)`` as in :func:`_dense_coupling`) in scipy.sparse."""
    import scipy.sparse as sp

    s = A.shape[0]
    n = X[0].size
    blocks_K, blocks_D = [], []
    for i in range(s):
        K, D = system.jacobians(X[i], V[i])
        blocks_K.append(_scaled(system, K, 1.0))
        blocks_D.append(_scaled(system, D, 1.0) if D is not None else sp.csr_matrix((n, n)))
    Ak = sp.kron(sp.csr_matrix(A), sp.identity(n), format="csr")
    return dt * dt * (Ak @ sp.block_diag(blocks_K, format="csr") @ Ak) \
        + dt * (Ak @ sp.block_diag(blocks_D, format="csr"))


def _scaled(system: System, lin: sp.spmatrix, factor: float):
    """``factor * M^-1 lin`` (rows scaled by the inverse masses; 0 on pinned particles)."""
    lin = lin.tocsr(copy=True)
    minv = np.repeat(system.inv_mass, system.dim)
    lin.data *= np.repeat(factor * minv, np.diff(lin.indptr))
    return lin


def newton_coupled(method: ImplicitRK, system: System, state: State,
                   dt: float) -> tuple[list[np.ndarray], list[np.ndarray], list[float]]:
    """Stage velocities, accelerations and powers of a fully implicit tableau (module docstring)."""
    A = method.A
    s = A.shape[0]
    shape = state.v.shape
    tol = method.rtol * _scale(state.v)

    def points(U: np.ndarray):
        V = U.reshape((s,) + shape)
        X = state.x[None] + dt * np.einsum("ij,jnd->ind", A, V)
        return X, V

    def residual(U: np.ndarray):
        X, V = points(U)
        evals = [system.rhs(X[i], V[i]) for i in range(s)]
        a = np.stack([e[0] for e in evals])
        G = V - state.v[None] - dt * np.einsum("ij,jnd->ind", A, a)
        return G.ravel(), (X, V, a, [e[1] for e in evals])

    def solve(point: tuple, r: np.ndarray):
        X, V, _, _ = point
        S = _dense_coupling(system, A, X, V, dt) if r.size <= factor.DENSE_MAX \
            else _sparse_coupling(system, A, X, V, dt)
        du, row_sum = _linear_solve(S, r)
        system.counters.n_factor += 1
        floor = 8.0 * np.finfo(float).eps * row_sum / dt * _scale(X) if row_sum > 0 else 0.0
        return du, floor

    U0 = np.tile(state.v.ravel(), s)
    _, (X, V, a, p) = _newton(system, U0, residual, solve, tol, method.max_iter, full_steps=4)
    return list(V), list(a), p
