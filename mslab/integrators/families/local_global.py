"""Local/global iteration for implicit Euler: the fast mass-spring method (Liu et al. 2013).

Implicit Euler's step is the minimiser of (eq. 27 of the lecture notes written as an optimisation)::

    g(x) = 1/(2 h^2) (x - y)^T M (x - y) + E(x),     y = x_n + h v_n,

with ``E`` the potential energy. For a Hooke spring ``k/2 (|x_i - x_j| - L)^2 =
min_{|d| = L} k/2 |x_i - x_j - d|^2``: with the spring directions ``d`` as extra unknowns
``g`` is quadratic in ``x``. Block coordinate descent alternates

* **local step**: every ``d_q`` is the projection of ``x_i - x_j`` on the sphere of radius
  ``L_q`` (:mod:`mslab.integrators.families.local_step`, compiled), and
* **global step**: ``(M + h gamma + h^2 L) x = M y + h gamma x_n + h^2 (J d + f_other)``,
  one solve with a constant matrix (``L`` the stiffness-weighted graph Laplacian, the same
  for every coordinate, so an ``n x n`` matrix with ``dim`` right-hand sides), factored once
  per system and dt and kept.

Each iteration decreases ``g``; its fixed point satisfies ``M (x - y) = h^2 f(x)``, implicit
Euler's equation, so with many iterations the method converges to implicit Euler's step
(and ``J d = f_spring(x) + L x`` makes it a quasi-Newton iteration with the constant
Hessian approximation ``M + h^2 L``). With a fixed small number of iterations (10 in the
paper) it stops early: cheap, stable, and more damped than implicit Euler.

Pinned particles move with their velocity (``x = x_n + h v_n``, as implicit Euler moves
them); their springs enter the right-hand side. Linear drag ``f = -gamma v`` (the Damping
effect) enters the constant matrix (``h gamma``: mass-proportional damping keeps the matrix
constant, as the paper's damping does). All other forces (gravity, anchors, colliders,
damping along springs) are evaluated at the current iterate ``(x^k, (x^k - x_n)/h)`` on the
right-hand side, so their fixed point is implicit Euler's too; stiff ones slow the
iteration (a contraction only while their stiffness is small against ``M/h^2 + L``).

**Cost.** Setup, once per system and dt (:func:`global_step`): the matrix, its
factorisation (CHOLMOD's symbolic analysis and numeric factorisation, counted in
``n_factor``; SuperLU without cvxopt) and, for Chebyshev, the spectral radius estimate
below. Per iteration: one compiled pass (local step and right-hand side,
:mod:`mslab.integrators.families.local_step`), the other effects' forces when they depend on the
state (gravity is a constant, evaluated once), one solve with the kept factors.

**Chebyshev acceleration** (``chebyshev=True``; Wang 2015, eq. 11-12): the plain iterate
``x^`` is relaxed and extrapolated as ``x^{k+1} = omega_{k+1} (relax (x^{k+1}^ - x^k) + x^k -
x^{k-1}) + x^{k-1}`` with ``omega = 1`` for the first ``delay`` iterations, ``omega = 2 / (2 -
r^2)`` at the next and ``omega_{k+1} = 4 / (4 - r^2 omega_k)`` after: the Chebyshev
semi-iteration for a linear fixed-point map whose spectrum lies in ``[-r, r]``. Same fixed
point as the plain iteration. Spectral radius: ``rho`` of the plain map, given or (``rho=None``)
estimated once per system and dt by :func:`spectral_radius`: power iteration
(:data:`POWER_ITERATIONS` steps from a fixed random start) on the map's linearisation at the
first step's inertial guess ``y``, ``delta -> Q^-1 h^2 [d(J d + f_other)/dx delta]_free``, the
derivative by a finite difference of the local step; each power step is one counted force
evaluation and solve. The estimate tends to ``rho`` (from below in practice: the safe side,
an over-estimate makes the extrapolation diverge); an estimate >= 1 (a map that does not
contract there) switches the extrapolation off. Wang's form takes
``relax = 1, r = rho`` (``one_sided=False``). The default (``one_sided=True``) uses that this
map's spectrum is one-sided, in ``[0, rho]``: the local step's derivative ``k L/l (I - u u^T)``
is positive semidefinite for any spring length ``l``, so ``Q^-1 h^2 J'`` is similar to a
positive semidefinite matrix (with springs, linear drag and constant forces only; other
effects may break it). Relaxing by ``relax = 2 / (2 - rho)`` maps ``[0, rho]`` onto ``[-r, r]``,
``r = rho / (2 - rho)``, a smaller radius: on the 81 x 81 cloth at h = 1/30, 10 iterations
land 0.086 of the step away from implicit Euler's result against 0.16 with Wang's form and
0.25 plain, 40 iterations 0.0065 / 0.013 / 0.13, at the plain iterations' cost per
iteration (``benchmarks/fast_mass_spring.py``, ``benchmarks/RESULTS.md``).

Reference: T. Liu, A. W. Bargteil, J. F. O'Brien, L. Kavan, "Fast Simulation of
Mass-Spring Systems", ACM Trans. Graph. 32(6), 209 (2013). H. Wang, "A Chebyshev
semi-iterative approach for accelerating projective and position-based dynamics", ACM
Trans. Graph. 34(6), 246 (2015). Related: projective dynamics (Bouaziz et al. 2014).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.base import Integrator
from mslab.integrators.families.local_global_loop import TreeIterations
from mslab.integrators.families.local_step import local_rhs, update
from mslab.integrators.newton.linear import DENSE_MAX, Factor
from mslab.integrators.newton.tree_solve import TreeSolve, tree_factor
from mslab.state import State

if TYPE_CHECKING:
    from mslab.system import System

_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: power-iteration steps of the spectral radius estimate (Chebyshev acceleration)
POWER_ITERATIONS = 30


class GlobalStep:
    """The constant global matrix ``Q = M + h gamma + h^2 L`` on the free particles, factored.

    Built once per (system, dt) and kept (:func:`global_step`); counts one ``n_factor``.
    """

    def __init__(self, system: System, dt: float):
        import scipy.sparse as sp  # on first use: `import mslab` stays cheap

        self.dt = dt
        # by the effects' declared capabilities: Hooke springs (i, j, k, L) and linear drag gamma
        springs = [e for e in system.effects if e.hooke_springs() is not None]
        tables = [e.hooke_springs() for e in springs]
        self.i = np.concatenate([t.i for t in tables]) if tables else np.zeros(0, np.int64)
        self.j = np.concatenate([t.j for t in tables]) if tables else np.zeros(0, np.int64)
        self.stiffness = np.concatenate([t.stiffness for t in tables]) if tables else np.zeros(0)
        self.rest_length = np.concatenate([t.rest_length for t in tables]) if tables else np.zeros(0)
        drags = [e for e in system.effects if e.linear_drag() is not None]
        self.gamma = sum(e.linear_drag() for e in drags)
        #: effects evaluated at the iterate: everything but Hooke springs and linear drag
        self.others = [e for e in system.effects if e not in springs and e not in drags]
        #: the others' forces that depend on neither x nor v (gravity), summed once
        self.constant = np.zeros((system.n_particles, system.dim))
        for e in self.others:
            f = e.constant_force()
            if f is not None:
                self.constant = self.constant + f
        self.varying = [e for e in self.others if e.constant_force() is None]
        #: springs with a velocity-dependent remainder (damping along the springs)
        self.damped_springs = [e for e in springs if e.velocity_dependent]
        n = system.n_particles
        k = self.stiffness
        lap = sp.coo_matrix((np.concatenate([k, k, -k, -k]),
                             (np.concatenate([self.i, self.j, self.i, self.j]),
                              np.concatenate([self.i, self.j, self.j, self.i]))), shape=(n, n)).tocsr()
        self.free = ~system.pinned
        self.free_idx = np.flatnonzero(self.free)
        # unsigned indices for the compiled pass: numba drops its negative-index test (the
        # spring kernel measured 0.81x with them, benchmarks/RESULTS.md)
        self.i_u, self.j_u = self.i.astype(np.uint32), self.j.astype(np.uint32)
        self.pinned = system.pinned.copy()
        self.rho: float | None = None  # the spectral radius estimate (Chebyshev), on first use
        self.loop: TreeIterations | None = None  # the compiled iterations (tree_iterations), on first use
        self.lap_fp = lap[self.free][:, self.pinned]
        Q = sp.diags(system.mass[self.free] + dt * self.gamma) + (dt * dt) * lap[self.free][:, self.free]
        Q = Q.tocsc()
        # ten solves per frame with this one matrix: its factors kept for solves on every core
        # (mslab.integrators.newton.tree_solve); small matrices and no cvxopt: Factor
        self.factor = tree_factor(Q, system.counters) if Q.shape[0] > DENSE_MAX else None
        if self.factor is None:
            self.factor = Factor(Q, system.counters)

    def other_forces(self, x: np.ndarray, xn: np.ndarray, dt: float) -> np.ndarray:
        """Return the other forces (all but springs and drag) at the iterate ``(x, (x - x_n)/h)``."""
        if not (self.varying or self.damped_springs):
            return self.constant
        out = self.constant.copy()
        v = (x - xn) / dt
        for e in self.varying:
            out += e.force(x, v)
        for e in self.damped_springs:  # the damping part of a damped spring
            out += e.force(x, v) - e.force(x, np.zeros_like(v))
        return out

    def rhs(self, x: np.ndarray, xn: np.ndarray, base: np.ndarray, dt: float, jd: np.ndarray,
            out: np.ndarray) -> None:
        """Local step at ``x``: ``jd = J d + f_other`` and ``out = base + h^2 jd[free]``."""
        local_rhs(x, self.i_u, self.j_u, self.stiffness, self.rest_length, self.other_forces(x, xn, dt),
                  base, dt * dt, self.free_idx, jd, out)


def spectral_radius(g: GlobalStep, system: System, x: np.ndarray, xn: np.ndarray, base: np.ndarray,
                    dt: float, steps: int = POWER_ITERATIONS) -> float:
    """Estimate the spectral radius of the local/global map's linearisation at ``x`` (power iteration).

    The map is ``x_free -> Q^-1 (base + h^2 jd(x)[free])``; its derivative applied to
    ``delta`` (pinned entries zero) is ``Q^-1 h^2 [jd(x + eps delta) - jd(x)]_free / eps``
    (``eps = 1e-6 (1 + max |x|)``, ``|delta| = 1``). ``steps`` steps from a fixed random start;
    each counts one force evaluation and one solve. Returns the last norm ratio.
    """
    c = system.counters
    free = g.free_idx
    jd0, jd1 = np.empty_like(x), np.empty_like(x)
    out = np.empty(base.shape, order="F")
    zero = np.zeros_like(base)
    g.rhs(x, xn, zero, dt, jd0, out)
    c.n_force += 1
    eps = 1e-6 * (1.0 + float(np.max(np.abs(x))))
    delta = np.random.default_rng(0).standard_normal(base.shape)
    rho = 0.0
    for _ in range(steps):
        delta /= np.linalg.norm(delta)
        moved = x.copy()
        moved[free] += eps * delta
        g.rhs(moved, xn, zero, dt, jd1, out)
        image = g.factor.solve(np.asfortranarray((dt * dt / eps) * (jd1[free] - jd0[free])))
        c.n_force += 1
        c.n_solve += 1
        rho = float(np.linalg.norm(image))
        if not np.isfinite(rho) or rho == 0.0:
            break
        delta = image
    return rho


def chebyshev_weights(rho: float, iterations: int, delay: int) -> np.ndarray:
    """``omega_k`` for ``k = 1 .. iterations`` (Wang 2015, eq. 12): 1 up to ``delay``, then Chebyshev's."""
    omega = np.ones(iterations)
    for k in range(delay, iterations):
        omega[k] = 2.0 / (2.0 - rho * rho) if k == delay else 4.0 / (4.0 - rho * rho * omega[k - 1])
    return omega


def tree_iterations(g: GlobalStep, system: System) -> TreeIterations | None:
    """Return the compiled loop of :mod:`~mslab.integrators.families.local_global_loop` for ``g``, or None.

    Only when the factors are split by the elimination tree (:class:`TreeSolve`), the scene is
    3D and the forces besides springs and drag are constant; built once per global step.
    """
    if not isinstance(g.factor, TreeSolve) or system.dim != 3 or g.varying or g.damped_springs:
        return None
    if g.loop is None:
        g.loop = TreeIterations(g, g.factor, system.mass)
    return g.loop


def global_step(system: System, dt: float) -> GlobalStep:
    """Return the kept :class:`GlobalStep` of ``system`` at step ``dt`` (built on first use)."""
    per_system = _CACHE.setdefault(system, {})
    if dt not in per_system:
        if len(per_system) > 8:
            per_system.clear()
        per_system[dt] = GlobalStep(system, dt)
    return per_system[dt]


class LocalGlobal(Integrator):
    """Implicit Euler's objective minimised by ``iterations`` local/global sweeps (module docstring).

    Parameters
    ----------
    name : str
    iterations : int
        Local/global iterations per step (the paper: 10).
    tol : float, optional
        Stop earlier once ``max |x^{k+1} - x^k| <= tol (1 + max |x_n|)``; None: always
        ``iterations`` sweeps. A bound on the last change, not on the error: the iteration
        contracts by about ``rho`` per sweep, so the iterate is about ``change / (1 - rho)``
        from implicit Euler's step (``rho`` near 1 on a stiff cloth: 0.999 at 25 x 25).
    doc : str, optional
    chebyshev : bool, optional
        Chebyshev acceleration (Wang 2015; module docstring): same fixed point, faster
        approach to it.
    rho : float, optional
        Chebyshev's spectral radius; None: estimated once per system and dt
        (:func:`spectral_radius`, counted).
    delay : int, optional
        Plain iterations before the Chebyshev extrapolation starts (Wang's ``S``).
    one_sided : bool, optional
        Relax by ``2 / (2 - rho)`` first (the map's spectrum is in ``[0, rho]``: module
        docstring); False: Wang's form, ``[-rho, rho]``.

    Cost per iteration: one force evaluation (the compiled local step for the springs, the
    other effects directly), one solve with the kept factors (``n_force``, ``n_solve``,
    ``n_iter`` counted; ``n_factor`` once per system and dt, with the spectral radius
    estimate's ``POWER_ITERATIONS`` force evaluations and solves for Chebyshev).
    """

    family = "local_global"
    #: the method whose step the iteration converges to (it minimises the same objective):
    #: :mod:`mslab.derive` reads the order there
    converges_to = "implicit_euler"
    explicit = False
    symplectic = False
    a_stable = True
    order = 1
    n_stages = 1

    def __init__(self, name: str = "local_global", iterations: int = 10, tol: float | None = None,
                 doc: str | None = None, chebyshev: bool = False, rho: float | None = None,
                 delay: int = 1, one_sided: bool = True):
        if iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {iterations}")
        if rho is not None and not 0.0 <= rho < 1.0:
            raise ValueError(f"rho must be in [0, 1), got {rho}")
        if delay < 1:
            raise ValueError(f"delay must be >= 1, got {delay}")
        self.name = name
        self.iterations = int(iterations)
        self.tol = tol
        self.chebyshev = bool(chebyshev)
        self.rho = rho
        self.delay = int(delay)
        self.one_sided = bool(one_sided)
        self.coefficients = {"iterations": self.iterations}
        if doc:
            self.__doc__ = doc

    # -- analysis: the linear limit ---------------------------------------------------------------
    def stability_function(self, z: np.ndarray) -> np.ndarray:
        """``R(z) = 1/(1 - z)``, implicit Euler's.

        In the linear limit (a spring along its own axis, as in the course's oscillator, or
        springs of zero rest length) the local step is exact and one global solve is
        implicit Euler's step, whatever the number of iterations.
        """
        z = np.asarray(z, dtype=complex)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(z == 1.0, np.inf, 1.0 / np.where(z == 1.0, 0.0, 1.0 - z))

    def oscillator_matrix(self, h_omega: np.ndarray, h_gamma: np.ndarray) -> np.ndarray:
        """Implicit Euler's map ``(I - dt J)^-1`` on the state ``(x, dt v)`` (linear limit)."""
        w2, g = np.broadcast_arrays(np.square(np.asarray(h_omega, dtype=float)),
                                    np.asarray(h_gamma, dtype=float))
        det = 1.0 + g + w2
        out = np.empty(w2.shape + (2, 2))
        out[..., 0, 0] = (1.0 + g) / det
        out[..., 0, 1] = 1.0 / det
        out[..., 1, 0] = -w2 / det
        out[..., 1, 1] = 1.0 / det
        return out

    # -- stepping ---------------------------------------------------------------------------------
    def start(self, system: System, state: State, dt: float) -> State:
        """Set up before the first frame: the global matrix's factorisation and Chebyshev's ``rho``.

        Counted as they happen (``n_factor``; the estimate's force evaluations and solves);
        a step without it does the same on first use. Returns ``state``.
        """
        if not system.pinned.all():
            g = global_step(system, dt)
            if self.chebyshev and self.rho is None and g.rho is None:
                y = state.x + dt * state.v
                self.weights(g, system, y, state.x, self._base(g, system, state, dt), dt)
        return state

    @staticmethod
    def _base(g: GlobalStep, system: System, state: State, dt: float) -> np.ndarray:
        """Return the constant part of the right-hand side, ``M y + h gamma x_n - h^2 L_fp x_p``."""
        y = state.x + dt * state.v
        free = g.free
        base = system.mass[free, None] * y[free] + (dt * g.gamma) * state.x[free]
        if g.lap_fp.nnz:
            base = base - (dt * dt) * (g.lap_fp @ y[g.pinned])
        return base

    def weights(self, g: GlobalStep, system: System, y: np.ndarray | None, xn: np.ndarray,
                base: np.ndarray | None, dt: float) -> tuple[np.ndarray, float]:
        """Return Chebyshev's weights ``omega_k`` and relaxation (1 without Chebyshev; module docstring)."""
        if not self.chebyshev:
            return np.ones(self.iterations), 1.0
        rho = self.rho
        if rho is None:
            if g.rho is None:  # setup: once per system and dt, at the first step's guess
                g.rho = spectral_radius(g, system, y, xn, base, dt)
            rho = g.rho
        if not 0.0 <= rho < 1.0:  # the plain iteration does not contract there: no extrapolation
            return np.ones(self.iterations), 1.0
        if not self.one_sided:
            return chebyshev_weights(rho, self.iterations, self.delay), 1.0
        return chebyshev_weights(rho / (2.0 - rho), self.iterations, self.delay), 2.0 / (2.0 - rho)

    def step(self, system: System, state: State, dt: float) -> State:
        """One step: ``iterations`` local/global sweeps from the inertial guess ``y``."""
        if system.pinned.all():  # nothing free: no global matrix to factor, every particle stays put
            return State(state.x + dt * state.v, state.v.copy(), (), state.dissipated)
        g = global_step(system, dt)
        c = system.counters
        xn, vn = state.x, state.v
        scale = 1.0 + float(np.max(np.abs(xn))) if xn.size else 1.0
        loop = tree_iterations(g, system)
        if loop is not None and (not self.chebyshev or self.rho is not None or g.rho is not None):
            # one compiled loop, one parallel launch per iteration: the same iterates
            omega, relax = self.weights(g, system, None, xn, None, dt)
            tol = -1.0 if self.tol is None else self.tol * scale
            x, done = loop.run(g, xn, vn, dt, omega, relax, self.chebyshev, tol)
            c.n_force += done
            c.n_solve += done
            return self._finish(system, state, x, done, dt)
        y = xn + dt * vn
        base = self._base(g, system, state, dt)
        omega, relax = self.weights(g, system, y, xn, base, dt)
        x = y.copy()
        prev = y.copy()  # the iterate before the last (Chebyshev)
        jd = np.empty_like(x)
        rhs = np.empty(base.shape, order="F")  # the solvers read columns
        done = 0
        while done < self.iterations:
            c.n_force += 1
            g.rhs(x, xn, base, dt, jd, rhs)
            new = g.factor.solve(rhs)
            c.n_solve += 1
            change = update(x, new, prev, g.free_idx, omega[done], relax, self.chebyshev)
            done += 1
            if not np.isfinite(change):
                break
            if self.tol is not None and change <= self.tol * scale:
                break
        return self._finish(system, state, x, done, dt)

    @staticmethod
    def _finish(system: System, state: State, x: np.ndarray, done: int, dt: float) -> State:
        """Return the step's state from the last iterate ``x`` (``done`` iterations counted)."""
        system.counters.n_iter += done
        v = (x - state.x) / dt
        v[system.pinned] = state.v[system.pinned]
        work = dt * system.dissipated_power(x, v) if system.dissipative else 0.0
        return State(x, v, (), state.dissipated + work)
