"""The linear solvers of the implicit methods: symmetric Newton matrices, kept factorisations, counted.

Newton's matrix of an implicit Euler-like stage ``V - v^ - c a(x^ + c V, V) = 0`` (``c = h g``)
is ``I - c M^-1 (c K + D)``. Scaled by the masses and restricted to the free degrees of
freedom (pinned particles keep ``V = v^``: their residual is zero from the start) it is::

    A = M - c^2 K - c D        (free dofs only)

symmetric whenever ``K = df/dx`` and ``D = df/dv`` are (springs, gravity, drag, anchors: all of
mslab's conservative and Rayleigh terms). ``A`` is the Hessian of the implicit Euler objective
(:func:`mslab.integrators.solvers.objective`), so it is positive definite near a stable step and the step is a
minimisation.

**Factorisation** (:class:`Factor`). Up to :data:`DENSE_MAX` unknowns dense LAPACK
(Cholesky, else LU). Above, CHOLMOD's supernodal sparse Cholesky through cvxopt (a
maintained binding with wheels; scikit-sparse has none for this Python here), about 10x
faster than SuperLU on a 100 x 100 cloth's matrix; it fails on a matrix that is not
positive definite. Newton's matrices are assembled on a sparsity pattern kept between
iterations and steps (:mod:`mslab.integrators.newton_matrix`), and CHOLMOD's symbolic
analysis of that pattern is done once: every later factorisation is numeric only.
Then (or without cvxopt) SuperLU in *symmetric mode*: a minimum-degree
ordering of ``A + A^T`` applied to rows and columns alike and no row pivoting
(``diag_pivot_thresh = 0``). That is an ``L D L^T`` factorisation written as ``L U``: the
signs of ``U``'s diagonal are the inertia of ``A`` (Sylvester's law), so the factorisation
itself tells whether and how ``A`` is indefinite.

**Fallback when A is not positive definite** (a compressed spring has negative stiffness
across it; hard compression makes ``A`` indefinite). The symmetric-mode factors are used
only when they solve ``A`` to 1e-8 (no pivoting can lose accuracy on an indefinite matrix);
otherwise SuperLU with partial pivoting (COLAMD ordering), a plain LU. Clamping the
compressed springs' stiffness would make every matrix definite, but was measured to break
Newton's convergence on the cloth at dt = 1/30: mslab keeps the exact Jacobian.

**Reuse** (:class:`StageSolver`): a factorisation is kept between Newton iterations and
steps. Each iteration takes (1) a *modified Newton* step with the kept factors (no
Jacobian, one solve) when the contraction measured on the last such step predicts that the
remaining modified steps cost less than a fresh factorisation (both counted in solves, with
the fixed ratio :data:`FACTOR_OVER_SOLVE`: never a timing, so a run is reproducible),
else (2) an inexact Newton step by conjugate gradients on the current ``A`` preconditioned
with the kept factors (the middle ground: one Jacobian, a few solves), else (3) a fresh
factorisation when CG is slow, meets negative curvature, or no definite factors are kept.

Counted on ``system.counters``: ``n_factor`` (every factorisation), ``n_solve`` (every
Newton direction), ``n_lin_iter`` (every CG iteration), ``n_jac`` (every Jacobian).
"""

from __future__ import annotations

import time
import weakref
from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.newton.newton_matrix import (
    FreePattern,
    cholmod_module,
    cholmod_solve,
    is_symmetric,
    one_shot_pattern,
)
from mslab.integrators.newton.pcg import pcg

if TYPE_CHECKING:  # scipy is imported on first use: `import mslab` stays cheap
    import scipy.sparse as sp

    from mslab.system import Counters, System

#: systems up to this many unknowns factor densely (LAPACK beats building scipy.sparse
#: objects there)
DENSE_MAX = 300

#: reuse policies: "fresh" factors every Newton matrix (the textbook method), "reuse" keeps
#: factorisations (see StageSolver), "auto" reuses above DENSE_MAX unknowns only
POLICIES = ("auto", "fresh", "reuse")
#: The cost of a factorisation (with the Newton matrix's assembly) in solves with its factors,
#: for the choice between a modified Newton step, CG and a fresh factorisation. Measured on
#: this machine's 100 x 100 cloth with the symbolic analysis kept: CHOLMOD's numeric
#: factorisation 0.10-0.15 s, assembly 0.02-0.03 s, a solve 0.010-0.013 s (benchmarks/RESULTS.md);
#: smaller cloths have larger ratios but cost little either way. A fixed ratio, not a
#: timing: the same run always takes the same steps, counts and results.
FACTOR_OVER_SOLVE = 12.0


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
                 pattern: FreePattern | None = None):
        start = time.perf_counter()
        self.pattern = pattern  # A's kept pattern (A is then pattern.matrix(data)), or None
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


class StageSolver:
    """Newton directions for stages with coefficient ``c`` on one System, factorisations kept.

    Parameters
    ----------
    system : System
    c : float
        ``h * A_ii``.
    policy : {"auto", "fresh", "reuse"}

    ``direction(point, r, jacobian)`` returns the Newton direction ``du`` (all dofs) for the
    residual ``r`` at ``point = (X, V)``; the solver picks modified Newton, CG with the kept
    factors, or a fresh factorisation (module docstring) and records ``row_sum`` (for the
    round-off floor of the tolerance).
    """

    #: CG stops at this relative residual (an inexact Newton step)
    cg_rtol: float = 1e-3
    #: CG gives up (and the matrix is factored afresh) after as many iterations as half a
    #: factorisation costs in solves (measured), within these bounds
    cg_iter_bounds: tuple = (4, 60)
    #: after CG preconditioned by an earlier stage's factors fails, so many stages start
    #: without trying it (on a cloth at dt = 1/60 it failed at every stage start: 17 % of the
    #: step's time measured at 100 x 100); a success keeps it on
    stale_cg_skip: int = 8

    def __init__(self, system: System, c: float, policy: str = "auto"):
        if policy not in POLICIES:
            raise ValueError(f"linear solver policy must be one of {POLICIES}, got {policy!r}")
        self.system = system
        self.c = float(c)
        self.free = np.repeat(~system.pinned, system.dim)
        self.mass_dofs = np.repeat(system.mass, system.dim)
        self.inv_mass_dofs = np.repeat(system.inv_mass, system.dim)
        self.pattern: FreePattern | None = None  # of the last Newton matrix
        n_free = int(np.count_nonzero(self.free))
        self.reuse = policy == "reuse" or (policy == "auto" and n_free > DENSE_MAX)
        self.factor: Factor | None = None
        self.rho = np.inf  # contraction of the last modified (or freshly factored) Newton step
        self.cg_ok = True  # the last CG attempt with the kept factors converged
        self.stage = 0  # counts the stages solved (see start_stage)
        self.row_sum = 0.0
        self.last = ""  # how the last direction was found: "modified", "cg" or "factor"
        self.mu = 4.0  # four times the next shift to try when A is indefinite
        self.stale_skip = 0  # stages left to start without CG on an earlier stage's factors

    def _assemble(self, point: tuple, r: np.ndarray):
        """Return ``A`` at ``point`` on the kept pattern (recorded again when the Jacobians' changes)."""
        stiff, damp = self.system.jacobian_terms(point[0], point[1])
        parts = stiff + damp  # none: no force depends on the state, A = M
        if self.pattern is None or not self.pattern.matches(parts):
            self.pattern = FreePattern(parts, self.free)
        c = self.c
        lin = np.concatenate([np.zeros(0)] + [p.data * (c * c) for p in stiff] + [p.data * c for p in damp])
        # row sums of the terms' |c M^-1 (c K_e + D_e)| (a bound on the round-off of the residual):
        # the floor of Newton's tolerance
        row = np.bincount(self.pattern.rows_in, np.abs(lin), self.free.size) * self.inv_mass_dofs
        self.row_sum = float(row.max()) if row.size else 0.0
        return self.pattern.assemble(lin, self.mass_dofs[self.free])

    def cg_max_iter(self) -> int:
        """Return the CG iterations worth half a fresh factorisation (:data:`FACTOR_OVER_SOLVE`)."""
        low, high = self.cg_iter_bounds
        return int(np.clip(0.5 * FACTOR_OVER_SOLVE, low, high))

    def rhs(self, r: np.ndarray) -> np.ndarray:
        """``-M r`` on the free dofs (the negative gradient of the objective)."""
        return -(self.mass_dofs[self.free] * r[self.free])

    def expand(self, du_free: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Return ``du_free`` on the free dofs and ``-r`` on the pinned ones, all dofs."""
        du = -r.astype(float, copy=True)  # pinned dofs: du = -r (zero: V = v^ there)
        du[self.free] = du_free
        return du

    def direction(self, point: tuple, r: np.ndarray, exact: bool = False, decades: float = 10.0,
                  definite_only: bool = False) -> np.ndarray | None:
        """Return the Newton direction for residual ``r`` (flat, all dofs) at ``point``.

        ``exact``: no modified Newton step (the current Jacobian is used). ``decades``: how
        many powers of ten the residual must still fall (for the cost model below).
        ``definite_only``: return None, instead of an indefinite factorisation's direction,
        when CHOLMOD finds ``A`` not positive definite (the caller shifts ``A``).

        With kept factors, a modified Newton step is taken when the predicted cost of the
        remaining modified steps (``decades / log10(1 / rho)`` solves at the last measured
        contraction ``rho``) is below that of a fresh factorisation plus three solves (a
        factorisation counted as :data:`FACTOR_OVER_SOLVE` solves: a fixed ratio, so the same
        run always takes the same steps and counts); else conjugate gradients on the current matrix
        preconditioned by the kept factors (while CG keeps succeeding; see
        :attr:`stale_cg_skip`); else a fresh factorisation.
        """
        c = self.system.counters
        b = self.rhs(r)
        c.n_solve += 1
        f = self.factor
        if self.reuse and f is not None and not exact and 0.0 < self.rho < 1.0:
            # a modified step costs its solve plus about as much for the residual and line search
            # (in units of one solve; a fixed ratio, never a timing, keeps runs reproducible)
            modified_cost = decades / np.log10(1.0 / self.rho) * 2.0
            if modified_cost <= FACTOR_OVER_SOLVE + 3.0:
                self.last = "modified"
                return self.expand(f.solve(b), r)
        A = self._assemble(point, r)
        # CG with factors from this stage, or from earlier steps while that keeps working
        fresh = getattr(f, "stage", None) == self.stage
        stale_ok = self.cg_ok and not self.stale_skip
        if self.reuse and f is not None and f.definite and (fresh or exact or stale_ok):
            x, its = pcg(A, b, f, self.cg_rtol if not exact else 1e-12, self.cg_max_iter())
            c.n_lin_iter += its
            self.cg_ok = x is not None
            if not (fresh or exact):
                self.stale_skip = 0 if self.cg_ok else self.stale_cg_skip
            if x is not None:
                self.last = "cg"
                return self.expand(x, r)
        self.factor = Factor(A, c, definite_only, pattern=self.pattern)
        self.factor.stage = self.stage
        self.last = "factor"
        if self.factor.kind == "none":
            return None
        return self.expand(self.factor.solve(b), r)

    def shifted_direction(self, r: np.ndarray) -> np.ndarray:
        """Return a descent direction when ``A`` is indefinite: ``(A + mu M)^-1 (-M r)`` (Levenberg).

        ``mu`` starts from a quarter of the last shift that worked (1 the first time) and is
        multiplied by 4 until the shifted matrix is positive definite; each try is one counted
        factorisation (by CHOLMOD when installed: an indefinite ``A`` costs no SuperLU then).
        """
        f = self.factor
        mass = self.mass_dofs[self.free]
        mu = self.mu / 4.0
        for _ in range(40):
            if f.pattern is not None:
                data = f.A.data.copy()
                data[f.pattern.diagonal] += mu * mass
                shifted = Factor(f.pattern.matrix(data), self.system.counters, definite_only=True,
                                 pattern=f.pattern)
            else:
                import scipy.sparse as sp

                shifted = Factor((f.A + mu * sp.diags(mass)).tocsc(), self.system.counters,
                                 definite_only=True)
            if shifted.definite:
                shifted.stage = self.stage
                self.factor, self.mu = shifted, mu  # a definite preconditioner for later CG
                self.rho = np.inf
                return self.expand(shifted.solve(self.rhs(r)), r)
            mu *= 4.0
        raise ArithmeticError("no positive definite shift of the Newton matrix found")

    def start_stage(self) -> None:
        """Start a new stage equation: the last contraction says nothing about modified steps here."""
        self.stage += 1
        self.rho = np.inf
        self.stale_skip = max(0, self.stale_skip - 1)

    def contracted(self, ratio: float) -> None:
        """Record the residual ratio ``|r_new| / |r_old|`` of the last full step (inf: damped).

        The contraction ``rho`` of a modified step (or of the fresh factorisation it would
        reuse) predicts the next modified steps; a CG step leaves it as it was.
        """
        if self.last in ("modified", "factor"):
            self.rho = ratio


_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def stage_solver(system: System, c: float, policy: str = "auto") -> StageSolver:
    """Return the kept :class:`StageSolver` of ``system`` for coefficient ``c`` and ``policy``."""
    per_system = _CACHE.setdefault(system, {})
    key = (float(c), policy)
    if key not in per_system:
        if len(per_system) > 8:
            per_system.clear()
        per_system[key] = StageSolver(system, c, policy)
    return per_system[key]
