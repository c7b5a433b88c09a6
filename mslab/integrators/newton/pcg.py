"""Conjugate gradients preconditioned by a kept factorisation: the middle ground of Newton's linear solves.

Used by :class:`mslab.integrators.newton.linear.StageSolver` as an inexact Newton step: the
current Newton matrix, preconditioned by factors of an earlier one (see that module).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp


class Preconditioner(Protocol):
    """Anything that solves with a kept factorisation (:class:`mslab.integrators.newton.linear.Factor`)."""

    def solve(self, rhs: np.ndarray) -> np.ndarray: ...  # noqa: D102


def pcg(A: sp.spmatrix, b: np.ndarray, precond: Preconditioner, rtol: float,
        max_iter: int) -> tuple[np.ndarray | None, int, float]:
    """Conjugate gradients on ``A x = b`` preconditioned by ``precond.solve``.

    Returns ``(x, iterations, |r| / |b|)``; ``x`` is None when CG does not reach
    ``|r| <= rtol |b|`` in ``max_iter`` iterations or meets a direction of non-positive
    curvature (``A`` not positive definite; the ratio is then inf). The ratio measures CG's
    rate (:class:`mslab.integrators.newton.linear.StageSolver`'s convergence model).
    """
    x = np.zeros_like(b)
    r = b.copy()
    bnorm = float(np.linalg.norm(b))
    if bnorm == 0.0:
        return x, 0, 0.0
    z = precond.solve(r)
    p = z.copy()
    rz = float(r @ z)
    for it in range(1, max_iter + 1):
        Ap = A @ p
        curvature = float(p @ Ap)
        if not curvature > 0.0:
            return None, it, np.inf
        alpha = rz / curvature
        x += alpha * p
        r -= alpha * Ap
        ratio = float(np.linalg.norm(r)) / bnorm
        if ratio <= rtol:
            return x, it, ratio
        z = precond.solve(r)
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return None, max_iter, ratio
