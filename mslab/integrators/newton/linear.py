"""The linear solvers of the implicit methods: symmetric Newton matrices, kept factorisations, counted.

Newton's matrix of an implicit Euler-like stage ``V - v^ - c a(x^ + c V, V) = 0`` (``c = h g``)
is ``I - c M^-1 (c K + D)``. Scaled by the masses and restricted to the free degrees of
freedom (pinned particles keep ``V = v^``: their residual is zero from the start) it is::

    A = M - c^2 K - c D        (free dofs only)

symmetric whenever ``K = df/dx`` and ``D = df/dv`` are (springs, gravity, drag, anchors: all of
mslab's conservative and Rayleigh terms). ``A`` is the Hessian of the implicit Euler objective
(:func:`mslab.integrators.newton.solvers.objective`), so it is positive definite near a
stable step and the step is a minimisation.

**Factorisation**: :class:`~mslab.integrators.newton.factor.Factor` (dense LAPACK for small
systems, CHOLMOD on the kept pattern, SuperLU's symmetric mode or partial pivoting for an
indefinite matrix). With ``precision="mixed"`` (above :data:`MIXED_MIN` unknowns, symmetric ``A``,
factors kept) a fresh factorisation is a float32 supernodal Cholesky (:mod:`~mslab.integrators.newton.mixed`)
preconditioning CG in float64 on ``A`` (to ``min(rtol, 1e-4)``, 1e-12 for an exact direction: mostly
one iteration); modified steps and CG with kept factors apply it as they apply float64 factors. A
pattern's first matrix is factored in float64 (the float32 analysis costs 0.15 s at 70 x 70,
CHOLMOD's 9 ms: a pattern changing at every iteration never pays it). When a float32 pivot is not
positive or CG with it does not converge, the float64 :class:`Factor` takes over for that matrix.

**Reuse** (:class:`StageSolver`): a factorisation is kept between Newton iterations and
steps. Each iteration takes (1) a *modified Newton* step with the kept factors (no
Jacobian, one solve) when the contraction measured on the last such step predicts that the
remaining modified steps cost less than a fresh factorisation (both counted in solves, with
the fixed ratio :data:`FACTOR_OVER_SOLVE`, :data:`MIXED_FACTOR_OVER_SOLVE` for float32 factors:
never a timing, so a run is reproducible),
else (2) an inexact Newton step by conjugate gradients on the current ``A`` preconditioned
with the kept factors, when a convergence model (:class:`StageSolver`) predicts that CG
converges within its budget (no solve is spent on a CG that will fail), else (3) a fresh
factorisation. On the compiled path (``backend="numba"``) ``A`` is written by compiled loops
straight into the kept pattern (:mod:`mslab.fast.newton_assembly`), and the option
``newton_hessian="clamped"`` drops every compressed spring's negative term (Choi & Ko 2002):
``A`` is then always positive definite, the residual stays exact.

Counted on ``system.counters``: ``n_factor`` (every factorisation), ``n_solve`` (every
Newton direction), ``n_lin_iter`` (every CG iteration), ``n_jac`` (every Jacobian).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING

import numpy as np

from mslab import jit
from mslab.integrators.newton.factor import DENSE_MAX, Factor
from mslab.integrators.newton.newton_matrix import FreePattern, cholmod_module
from mslab.integrators.newton.pcg import pcg

__all__ = ["DENSE_MAX", "FACTOR_OVER_SOLVE", "MIXED_FACTOR_OVER_SOLVE", "MIXED_MIN", "POLICIES", "PRECISIONS",
           "Factor", "StageSolver", "forget", "stage_solver"]

if TYPE_CHECKING:  # scipy is imported on first use: `import mslab` stays cheap
    import scipy.sparse as sp

    from mslab.system import System

#: reuse policies: "fresh" factors every Newton matrix (the textbook method), "reuse" keeps
#: factorisations (see StageSolver), "auto" reuses above DENSE_MAX unknowns only
POLICIES = ("auto", "fresh", "reuse")
#: precisions of the kept factorisations: "mixed" (float32 factors preconditioning CG in float64,
#: where factors are kept and the matrix is large, sparse and symmetric) or "double" (float64 factors)
PRECISIONS = ("mixed", "double")
#: "mixed" factors in float32 above this many unknowns only: below, CHOLMOD's float64 factorisation
#: costs little against the solves (0.7 ms at 426 unknowns) and the float32 path's extra CG
#: iterations do not pay (measured on cloths in benchmarks/RESULTS.md, issue 38 item 4)
MIXED_MIN = 10_000
#: The cost of a factorisation (with the Newton matrix's assembly) in solves with its factors,
#: for the choice between a modified Newton step, CG and a fresh factorisation. Measured on
#: this machine's 100 x 100 cloth with the symbolic analysis kept: CHOLMOD's numeric
#: factorisation 0.10-0.15 s, assembly 0.02-0.03 s, a solve 0.010-0.013 s (benchmarks/RESULTS.md);
#: smaller cloths have larger ratios but cost little either way. A fixed ratio, not a
#: timing: the same run always takes the same steps, counts and results.
FACTOR_OVER_SOLVE = 12.0
#: the same ratio for float32 factors: one costs 20-27 of their solves (float32 BLAS) at 70 x 70;
#: interleaved on 70 x 70 and 100 x 100 cloths 40 beat 6 to 30 (one factorisation a step instead
#: of 2.7-3, more CG iterations), 60 was within the noise (benchmarks/RESULTS.md, issue 38 item 4)
MIXED_FACTOR_OVER_SOLVE = 40.0


class StageSolver:
    """Newton directions for stages with coefficient ``c`` on one System, factorisations kept.

    Parameters
    ----------
    system : System
    c : float
        ``h * A_ii``.
    policy : {"auto", "fresh", "reuse"}
    clamp : bool
        Newton's matrix with every spring's compressive term dropped (positive definite;
        the compiled path only, see :mod:`mslab.fast.newton_assembly`).
    precision : {"mixed", "double"}
        Fresh factorisations in float32 preconditioning CG in float64 (module docstring), or in
        float64.

    ``direction(point, r, jacobian)`` returns the Newton direction ``du`` (all dofs) for the
    residual ``r`` at ``point = (X, V)``; the solver picks modified Newton, CG with the kept
    factors, or a fresh factorisation (module docstring) and records ``row_sum`` (for the
    round-off floor of the tolerance).

    **When CG is tried** (a convergence model, not a trial): with kept factors of ``A_f``,
    CG on ``A`` converges at the rate ``q = delta / (1 + sqrt(1 - delta^2))`` per iteration
    when the spectrum of ``A_f^-1 A`` lies within ``1 +- delta`` (the classical bound,
    ``kappa = (1 + delta) / (1 - delta)``). The solver measures the relative change
    ``e = |A - A_f|_F / |A_f|_F`` (one pass over ``A``'s values) and models
    ``delta = beta e / (1 + beta e)``: linear for small changes, saturating below 1 as
    measured on the cloth (CG's rate stays near 0.65 for changes from 1e-2 to 2e-2: a few
    outlying eigenvalues, which CG removes one per iteration). ``beta`` starts at
    :attr:`cg_rate_per_change` and is re-fitted to the rate of every CG run
    (``(|r_end| / |b|)^(1 / iterations)``), one ``beta`` for factors of the same stage and
    one for factors of an earlier step (whose change spans a whole step: measured slower).
    CG runs only when ``log(rtol) / log(q)`` iterations fit in :meth:`cg_max_iter`; else the
    matrix is factored at once. The same bound decides whether factors are reused in a
    later step: they are while the predicted CG converges within the budget.
    """

    #: CG stops at this relative residual (an inexact Newton step) unless the caller gives one
    cg_rtol: float = 1e-3
    #: the loosest relative residual a caller's forcing term asks of CG
    cg_rtol_max: float = 0.1
    #: CG gives up (and the matrix is factored afresh) after as many iterations as half a
    #: factorisation costs in solves (measured), within these bounds
    cg_iter_bounds: tuple = (4, 60)
    #: the first ``beta`` of the convergence model (refitted by every CG run): measured on the
    #: 70 x 70 cloth at dt = 1/60 (rates 0.08, 0.3, 0.65 at changes 3e-4, 1e-3, 2e-2)
    cg_rate_per_change: float = 600.0

    def __init__(self, system: System, c: float, policy: str = "auto", clamp: bool = False,
                 precision: str = "mixed"):
        if policy not in POLICIES:
            raise ValueError(f"linear solver policy must be one of {POLICIES}, got {policy!r}")
        if precision not in PRECISIONS:
            raise ValueError(f"factor precision must be one of {PRECISIONS}, got {precision!r}")
        self.system = system
        self.c = float(c)
        self.free = np.repeat(~system.pinned, system.dim)
        self.mass_dofs = np.repeat(system.mass, system.dim)
        self.inv_mass_dofs = np.repeat(system.inv_mass, system.dim)
        self.pattern: FreePattern | None = None  # of the last Newton matrix
        n_free = int(np.count_nonzero(self.free))
        self.reuse = policy == "reuse" or (policy == "auto" and n_free > DENSE_MAX)
        # float32 factors: large (above MIXED_MIN), kept; AMD from cvxopt, the loops compiled by numba
        self.mixed = (precision == "mixed" and self.reuse and n_free > max(MIXED_MIN, DENSE_MAX)
                      and cholmod_module() is not None and jit.available())
        self.factor_over_solve = MIXED_FACTOR_OVER_SOLVE if self.mixed else FACTOR_OVER_SOLVE
        self._factored: FreePattern | None = None  # the pattern of the last fresh factorisation
        self.factor: Factor | None = None
        self.rho = np.inf  # contraction of the last modified (or freshly factored) Newton step
        # the model's beta for factors of this stage (True) and of an earlier one (False)
        self.beta = {True: self.cg_rate_per_change, False: self.cg_rate_per_change}
        self.stage = 0  # counts the stages solved (see start_stage)
        self.row_sum = 0.0
        self.last = ""  # how the last direction was found: "modified", "cg" or "factor"
        self.mu = 4.0  # four times the next shift to try when A is indefinite
        make = getattr(system, "newton_assembly", None)  # the compiled path's assembly
        if clamp and make is None:
            raise ValueError("the clamped Newton matrix is assembled by compiled loops: use backend='numba'")
        self.compiled = make(self.c, self.free, clamp) if make is not None else None
        self.symmetric: bool | None = None  # A is symmetric whatever the state (None: not known)

    def _assemble(self, point: tuple, r: np.ndarray):
        """Return ``A`` at ``point`` on the kept pattern (recorded again when the Jacobians' changes).

        Also sets :attr:`row_sum`, ``max_i m_i^-1 sum_j |A_ij - M_ij|`` (a bound on the
        round-off of the residual: the floor of Newton's tolerance).
        """
        if self.compiled is not None:
            A, self.row_sum = self.compiled.assemble(point[0], point[1])
            self.pattern = self.compiled.pattern
            self.symmetric = True if self.compiled.symmetric else None
            return A
        stiff, damp = self.system.jacobian_terms(point[0], point[1])
        parts = stiff + damp  # none: no force depends on the state, A = M
        if self.pattern is None or not self.pattern.matches(parts):
            self.pattern = FreePattern(parts, self.free)
        c = self.c
        lin = np.concatenate([np.zeros(0)] + [p.data * (c * c) for p in stiff] + [p.data * c for p in damp])
        mass = self.mass_dofs[self.free]
        A = self.pattern.assemble(lin, mass)
        off = np.abs(A.data)
        off[self.pattern.diagonal] = np.abs(A.data[self.pattern.diagonal] - mass)
        row = np.add.reduceat(off, A.indptr[:-1]) / mass  # every row holds its diagonal: none is empty
        self.row_sum = float(row.max()) if row.size else 0.0
        return A

    def cg_max_iter(self) -> int:
        """Return the CG iterations worth half a fresh factorisation (:attr:`factor_over_solve` solves)."""
        low, high = self.cg_iter_bounds
        return int(np.clip(0.5 * self.factor_over_solve, low, high))

    def change(self, A: sp.spmatrix) -> float:
        """Return ``|A - A_f|_F / |A_f|_F`` against the kept factors' matrix (inf: another pattern)."""
        f = self.factor
        if f is None or f.pattern is not self.pattern or self.pattern is None:
            return np.inf
        if self.compiled is not None:
            return self.compiled.change(A.data, f.A.data)
        return float(np.linalg.norm(A.data - f.A.data) / np.linalg.norm(f.A.data))

    def predicted_cg_iterations(self, change: float, rtol: float) -> float:
        """Return the CG iterations the model (class docstring) predicts for a relative ``change``.

        inf for an infinite change (the kept factors belong to another pattern: no CG).
        """
        if not np.isfinite(change):
            return np.inf
        x = self.beta[self._same_stage()] * change
        delta = x / (1.0 + x)  # the spectrum of A_f^-1 A within 1 +- delta
        q = delta / (1.0 + np.sqrt(1.0 - delta * delta))
        return 1.0 if q <= 0.0 else max(1.0, float(np.log(rtol) / np.log(q)))

    def refit(self, change: float, rate: float) -> None:
        """Fit ``beta`` to CG's measured ``rate`` per iteration at a relative ``change``.

        Only a measured rate below 1 at a finite, positive change refits the model (negative
        curvature measures no rate: the matrix is indefinite, not the factors stale).
        """
        if not (0.0 < change < np.inf and 0.0 <= rate < 1.0):
            return
        rate = min(rate, 0.999)
        delta = 2.0 * rate / (1.0 + rate * rate)  # the inverse of the rate's formula
        self.beta[self._same_stage()] = delta / ((1.0 - delta) * change)

    def _same_stage(self) -> bool:
        return getattr(self.factor, "stage", None) == self.stage

    def rhs(self, r: np.ndarray) -> np.ndarray:
        """``-M r`` on the free dofs (the negative gradient of the objective)."""
        return -(self.mass_dofs[self.free] * r[self.free])

    def expand(self, du_free: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Return ``du_free`` on the free dofs and ``-r`` on the pinned ones, all dofs."""
        du = -r.astype(float, copy=True)  # pinned dofs: du = -r (zero: V = v^ there)
        du[self.free] = du_free
        return du

    def direction(self, point: tuple, r: np.ndarray, exact: bool = False, decades: float = 10.0,
                  definite_only: bool = False, rtol: float | None = None) -> np.ndarray | None:
        """Return the Newton direction for residual ``r`` (flat, all dofs) at ``point``.

        ``exact``: no modified Newton step (the current Jacobian is used). ``decades``: how
        many powers of ten the residual must still fall (for the cost model below).
        ``definite_only``: return None, instead of an indefinite factorisation's direction,
        when CHOLMOD finds ``A`` not positive definite (the caller shifts ``A``). ``rtol``:
        the relative residual CG stops at (the caller's forcing term; default :attr:`cg_rtol`).

        With kept factors, a modified Newton step is taken when the predicted cost of the
        remaining modified steps (``decades / log10(1 / rho)`` solves at the last measured
        contraction ``rho``) is below that of a fresh factorisation plus three solves (a
        factorisation counted as :data:`FACTOR_OVER_SOLVE` solves: a fixed ratio, so the same
        run always takes the same steps and counts); else conjugate gradients on the current
        matrix preconditioned by the kept factors when the convergence model (class
        docstring) predicts that CG converges within :meth:`cg_max_iter` iterations; else a
        fresh factorisation.
        """
        c = self.system.counters
        b = self.rhs(r)
        c.n_solve += 1
        f = self.factor
        if self.reuse and f is not None and not exact and 0.0 < self.rho < 1.0:
            # a modified step costs its solve plus about as much for the residual and line search
            # (in units of one solve; a fixed ratio, never a timing, keeps runs reproducible)
            modified_cost = decades / np.log10(1.0 / self.rho) * 2.0
            if modified_cost <= self.factor_over_solve + 3.0:
                self.last = "modified"
                return self.expand(f.solve(b), r)
        A = self._assemble(point, r)
        rtol = 1e-12 if exact else (self.cg_rtol if rtol is None else max(rtol, 1e-12))
        if self.reuse and f is not None and f.definite:
            change = self.change(A)
            if self.predicted_cg_iterations(change, rtol) <= self.cg_max_iter():
                x, its, ratio = pcg(A, b, f, rtol, self.cg_max_iter())
                c.n_lin_iter += its
                if its and ratio < 1.0:  # refit the model to the rate measured
                    self.refit(change, ratio ** (1.0 / its))
                if x is not None:
                    self.last = "cg"
                    return self.expand(x, r)
        self.last = "factor"
        # a pattern factored before (or analysed): its float32 analysis pays; one met once (contacts
        # changing every iteration) is factored by CHOLMOD, whose analysis is cheaper
        again = self.pattern is self._factored or getattr(self.pattern, "mixed", None) is not None
        self._factored = self.pattern
        if self.mixed and again:
            x = self._mixed_direction(A, b, rtol)
            if x is not None:
                return self.expand(x, r)
        self.factor = Factor(A, c, definite_only, pattern=self.pattern, symmetric=self.symmetric)
        self.factor.stage = self.stage
        if self.factor.kind == "none":
            return None
        return self.expand(self.factor.solve(b), r)

    def _mixed_direction(self, A: sp.csr_matrix, b: np.ndarray, rtol: float) -> np.ndarray | None:
        """Return ``A^-1 b`` by CG preconditioned with a fresh float32 factor (kept), or None.

        None (and nothing kept) when ``A`` is not symmetric, the float32 factorisation meets a
        pivot that is not positive, or CG does not reach ``min(rtol, FRESH_RTOL)`` within
        ``FRESH_MAX_ITER`` iterations: the caller factors in float64.
        """
        from mslab.integrators.newton.mixed import FRESH_MAX_ITER, FRESH_RTOL, mixed_factor

        symmetric = self.symmetric if self.symmetric is not None else self.pattern.symmetric(A.data)
        if not symmetric:
            return None
        c = self.system.counters
        factor = mixed_factor(A, c, self.pattern, self.system.dim)
        if factor is None:
            return None
        x, its, _ = pcg(A, b, factor, min(rtol, FRESH_RTOL), FRESH_MAX_ITER)
        c.n_lin_iter += its
        if x is None:
            return None
        factor.stage = self.stage
        self.factor = factor
        return x

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
                                 pattern=f.pattern, symmetric=self.symmetric)
            else:
                import scipy.sparse as sp

                shifted = Factor((f.A + mu * sp.diags(mass)).tocsc(), self.system.counters,
                                 definite_only=True)
            if shifted.definite:
                shifted.stage = self.stage
                self.factor, self.mu = shifted, mu  # a definite preconditioner for later CG
                self.rho, self.last = np.inf, "shifted"
                return self.expand(shifted.solve(self.rhs(r)), r)
            mu *= 4.0
        raise ArithmeticError("no positive definite shift of the Newton matrix found")

    def indefinite_direction(self, r: np.ndarray) -> np.ndarray:
        """Return Newton's own direction ``A^-1 (-M r)`` for an indefinite ``A`` (no shift).

        ``A`` is the matrix CHOLMOD just refused; it is factored by SuperLU (symmetric mode,
        else partial pivoting: :class:`~mslab.integrators.newton.factor.Factor`). Near a root
        of the step equation that is a saddle of implicit Euler's objective, this converges
        where shifted (minimising) steps crawl.
        """
        f = self.factor
        plain = Factor(f.A, self.system.counters, pattern=f.pattern, symmetric=self.symmetric)
        plain.stage = self.stage
        self.factor, self.rho, self.last = plain, np.inf, "indefinite"
        return self.expand(plain.solve(self.rhs(r)), r)

    def start_stage(self) -> None:
        """Start a new stage equation: the last contraction says nothing about modified steps here."""
        self.stage += 1
        self.rho = np.inf

    def contracted(self, ratio: float) -> None:
        """Record the residual ratio ``|r_new| / |r_old|`` of the last full step (inf: damped).

        The contraction ``rho`` of a modified step (or of the fresh factorisation it would
        reuse) predicts the next modified steps; a CG step leaves it as it was.
        """
        if self.last in ("modified", "factor"):
            self.rho = ratio


_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def forget(system: System) -> None:
    """Drop the stage solvers (and their kept factorisations) of ``system``: a new run starts clean."""
    _CACHE.pop(system, None)


def stage_solver(system: System, c: float, policy: str = "auto", clamp: bool = False,
                 precision: str = "mixed") -> StageSolver:
    """Return the kept :class:`StageSolver` of ``system`` for ``c``, ``policy``, ``clamp``, ``precision``."""
    per_system = _CACHE.setdefault(system, {})
    key = (float(c), policy, bool(clamp), precision)
    if key not in per_system:
        if len(per_system) > 8:
            per_system.clear()
        per_system[key] = StageSolver(system, c, policy, clamp, precision)
    return per_system[key]
