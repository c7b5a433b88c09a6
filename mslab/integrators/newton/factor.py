"""A factorisation of one symmetric Newton matrix ``A`` (free dofs), counted in ``n_factor``.

Up to :data:`DENSE_MAX` unknowns dense LAPACK
(Cholesky, else LU). Above, CHOLMOD's supernodal sparse Cholesky through cvxopt (a
maintained binding with wheels; scikit-sparse has none for this Python here), about 10x
faster than SuperLU on a 100 x 100 cloth's matrix; it fails on a matrix that is not
positive definite. Newton's matrices are assembled on a sparsity pattern kept between
iterations and steps (:mod:`mslab.integrators.newton.newton_matrix`), and CHOLMOD's symbolic
analysis of that pattern is done once: every later factorisation is numeric only.
Then (or without cvxopt) SuperLU in *symmetric mode*: a minimum-degree
ordering of ``A + A^T`` applied to rows and columns alike and no row pivoting
(``diag_pivot_thresh = 0``). That is an ``L D L^T`` factorisation written as ``L U``: the
signs of ``U``'s diagonal are the inertia of ``A`` (Sylvester's law), so the factorisation
itself tells whether and how ``A`` is indefinite.

**Fallback when A is not positive definite** (a compressed spring has negative stiffness
across it; hard compression makes ``A`` indefinite). The symmetric-mode factors are used
only when they solve ``A`` to 1e-8 (no pivoting can lose accuracy on an indefinite matrix);
otherwise SuperLU with partial pivoting (COLAMD ordering), a plain LU. (The option
``newton_hessian="clamped"`` of :mod:`mslab.integrators.newton.linear` makes every matrix
definite instead.)
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.newton.newton_matrix import (
    FreePattern,
    cholmod_module,
    cholmod_solve,
    is_symmetric,
    one_shot_pattern,
)

if TYPE_CHECKING:  # scipy is imported on first use: `import mslab` stays cheap
    import scipy.sparse as sp

    from mslab.system import Counters

#: systems up to this many unknowns factor densely (LAPACK beats building scipy.sparse
#: objects there)
DENSE_MAX = 300


class Factor:
    """A factorisation of one symmetric matrix ``A`` (scipy sparse, free dofs).

    Attributes
    ----------
    A : sparse matrix, shape (n, n)
        The factored matrix (kept for CG and for the accuracy check).
    definite : bool
        ``A`` is positive definite (all pivots of the symmetric factorisation > 0).
    n_negative : int
        Negative pivots: the number of negative eigenvalues of ``A`` (-1: not known).
    kind : str
        ``"cholesky"`` / ``"lu"`` (dense), ``"cholmod"``, ``"ldlt"`` (symmetric-mode SuperLU),
        ``"lu_pivoted"``.
    """

    def __init__(self, A: sp.spmatrix | np.ndarray, counters: Counters, definite_only: bool = False,
                 pattern: FreePattern | None = None, symmetric: bool | None = None):
        start = time.perf_counter()
        self.pattern = pattern  # A's kept pattern (A is then pattern.matrix(data)), or None
        self._symmetric = symmetric  # known by the caller (None: tested here)
        self._build(A, counters, definite_only)
        self.seconds = time.perf_counter() - start  # wall time of the factorisation (lesson 04 shows it)

    def _build(self, A: sp.spmatrix | np.ndarray, counters: Counters, definite_only: bool) -> None:
        import scipy.linalg as sla
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        counters.n_factor += 1
        self.A = A
        self.n_negative = -1
        n = A.shape[0]
        symmetric = self._symmetric
        if symmetric is None:
            symmetric = self.pattern.symmetric(A.data) if self.pattern is not None else is_symmetric(A)
        if n <= DENSE_MAX:
            dense = A.toarray() if sp.issparse(A) else np.asarray(A)
            if not symmetric:  # friction: D = df/dv is not symmetric, Cholesky would read half of A
                self._lu = sla.lu_factor(dense, check_finite=False)
                self.kind, self.definite = "lu", False
                return
            try:
                self._cho = sla.cho_factor(dense, lower=True, check_finite=False)
                self.kind, self.definite, self.n_negative = "cholesky", True, 0
            except sla.LinAlgError:
                self._lu = sla.lu_factor(dense, check_finite=False)
                self.kind, self.definite = "lu", False
            return
        if not symmetric:
            self._splu = spla.splu(A.tocsc())  # partial pivoting: the only sound choice for a nonsymmetric A
            self.kind, self.definite = "lu_pivoted", False
            return
        if self._cholmod(A):
            return
        if definite_only and cholmod_module() is not None:  # the caller shifts A instead
            self.kind, self.definite = "none", False
            return
        A = A.tocsc()
        try:
            lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
        except RuntimeError:  # an exactly zero pivot: singular without pivoting
            lu = None
        if lu is not None and np.array_equal(lu.perm_r, lu.perm_c):
            pivots = lu.U.diagonal()
            self.n_negative = int(np.count_nonzero(pivots < 0))
            self.definite = self.n_negative == 0 and bool(np.all(np.isfinite(pivots)))
            self._splu, self.kind = lu, "ldlt"
            if self.definite or self._accurate():
                return
        counters.n_factor += 1
        self._splu = spla.splu(A)  # partial pivoting: the fallback for indefinite matrices
        self.kind, self.definite = "lu_pivoted", False

    def _cholmod(self, A: sp.spmatrix) -> bool:
        """Factor ``A`` by CHOLMOD on its kept pattern (symbolic analysis reused); False if not definite.

        Also False when cvxopt is not installed (SuperLU takes over).
        """
        if cholmod_module() is None:
            return False
        if self.pattern is None:  # a matrix met once: its own pattern
            self._own_pattern, data = one_shot_pattern(A)
            F = self._own_pattern.cholmod(self, data)
        else:
            F = self.pattern.cholmod(self, A.data)
        if F is None:
            return False
        self._chol = F
        self.kind, self.definite, self.n_negative = "cholmod", True, 0
        return True

    def _accurate(self) -> bool:
        """Check that the unpivoted factors solve ``A`` to a relative 1e-8 (on a random right side)."""
        b = np.random.default_rng(0).standard_normal(self.A.shape[0])
        x = self._splu.solve(b)
        return bool(np.all(np.isfinite(x)) and np.linalg.norm(self.A @ x - b) <= 1e-8 * np.linalg.norm(b))

    solve_seconds: float = 0.0  # wall time of the last solve (lesson 04 shows it; no decision reads it)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` (timed)."""
        start = time.perf_counter()
        x = self._solve(b)
        self.solve_seconds = time.perf_counter() - start
        return x

    def _solve(self, b: np.ndarray) -> np.ndarray:
        import scipy.linalg as sla

        if self.kind == "cholmod":
            if (self.pattern or self._own_pattern).owner is not self:
                raise RuntimeError("this CHOLMOD factorisation was overwritten by a later one on its pattern")
            return cholmod_solve(self._chol, b)
        if self.kind == "cholesky":
            return sla.cho_solve(self._cho, b, check_finite=False)
        if self.kind == "lu":
            return sla.lu_solve(self._lu, b, check_finite=False)
        return self._splu.solve(b)
