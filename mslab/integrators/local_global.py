"""Local/global iteration for implicit Euler: the fast mass-spring method (Liu et al. 2013).

Implicit Euler's step is the minimiser of (seed eq. 27 written as an optimisation)::

    g(x) = 1/(2 h^2) (x - y)^T M (x - y) + E(x),     y = x_n + h v_n,

with ``E`` the potential energy. For a Hooke spring ``k/2 (|x_i - x_j| - L)^2 =
min_{|d| = L} k/2 |x_i - x_j - d|^2``: with the spring directions ``d`` as extra unknowns
``g`` is quadratic in ``x``. Block coordinate descent alternates

* **local step**: every ``d_q`` is the projection of ``x_i - x_j`` on the sphere of radius
  ``L_q`` (:mod:`mslab.integrators.local_step`, compiled), and
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

Reference: T. Liu, A. W. Bargteil, J. F. O'Brien, L. Kavan, "Fast Simulation of
Mass-Spring Systems", ACM Trans. Graph. 32(6), 209 (2013). Related: projective dynamics
(Bouaziz et al. 2014).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.base import Integrator
from mslab.integrators.linear import Factor
from mslab.integrators.local_step import projections
from mslab.state import State

if TYPE_CHECKING:
    from mslab.system import System

_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


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
        #: springs with a velocity-dependent remainder (damping along the springs)
        self.damped_springs = [e for e in springs if e.velocity_dependent]
        n = system.n_particles
        k = self.stiffness
        lap = sp.coo_matrix((np.concatenate([k, k, -k, -k]),
                             (np.concatenate([self.i, self.j, self.i, self.j]),
                              np.concatenate([self.i, self.j, self.j, self.i]))), shape=(n, n)).tocsr()
        self.free = ~system.pinned
        self.pinned = system.pinned.copy()
        self.lap_fp = lap[self.free][:, self.pinned]
        Q = sp.diags(system.mass[self.free] + dt * self.gamma) + (dt * dt) * lap[self.free][:, self.free]
        self.factor = Factor(Q.tocsc(), system.counters)


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
        ``iterations`` sweeps.
    doc : str, optional

    Cost per iteration: one force evaluation (the compiled local step for the springs, the
    other effects directly), one solve with the kept factors (``n_force``, ``n_solve``,
    ``n_iter`` counted; ``n_factor`` once per system and dt).
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
                 doc: str | None = None):
        if iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {iterations}")
        self.name = name
        self.iterations = int(iterations)
        self.tol = tol
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
    def step(self, system: System, state: State, dt: float) -> State:
        """One step: ``iterations`` local/global sweeps from the inertial guess ``y``."""
        if system.pinned.all():  # nothing free: no global matrix to factor, every particle stays put
            return State(state.x + dt * state.v, state.v.copy(), (), state.dissipated)
        g = global_step(system, dt)
        c = system.counters
        xn, vn = state.x, state.v
        y = xn + dt * vn
        free = g.free
        # constant part of the right-hand side: M y + h gamma x_n - h^2 L_fp x_p (pinned x = y)
        base = system.mass[free, None] * y[free] + (dt * g.gamma) * xn[free]
        if g.lap_fp.nnz:
            base = base - (dt * dt) * (g.lap_fp @ y[g.pinned])
        x = y.copy()
        scale = 1.0 + float(np.max(np.abs(xn))) if xn.size else 1.0
        jd = np.empty_like(x)
        done = 0
        while done < self.iterations:
            done += 1
            c.n_force += 1
            jd[:] = 0.0
            projections(x, g.i, g.j, g.stiffness, g.rest_length, jd)
            if g.others or g.damped_springs:
                v = (x - xn) / dt
                for e in g.others:
                    jd += e.force(x, v)
                for e in g.damped_springs:  # the damping part of a damped spring
                    jd += e.force(x, v) - e.force(x, np.zeros_like(v))
            rhs = np.asfortranarray(base + (dt * dt) * jd[free])  # SuperLU solves columns
            new = g.factor.solve(rhs)
            c.n_solve += 1
            change = float(np.max(np.abs(new - x[free]))) if new.size else 0.0
            x[free] = new
            if not np.isfinite(change):
                break
            if self.tol is not None and change <= self.tol * scale:
                break
        c.n_iter += done
        v = (x - xn) / dt
        v[g.pinned] = vn[g.pinned]
        work = dt * system.dissipated_power(x, v) if system.dissipative else 0.0
        return State(x, v, (), state.dissipated + work)
