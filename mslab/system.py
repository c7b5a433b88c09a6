"""The System: masses, pinned particles, the scene's effects and the work counters.

Every force evaluation of a run goes through :meth:`System.acceleration` or
:meth:`System.rhs`, which count it; Jacobian assemblies, linear solves and
iterations are counted here too. Counting, not estimating, is what makes the
accuracy-versus-cost comparisons honest.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np

from mslab.effects.base import Effect
from mslab.lanes import state_sums

if TYPE_CHECKING:  # scipy.sparse is imported on first use: `import mslab` stays cheap
    from collections.abc import Iterable

    import numpy.typing as npt
    import scipy.sparse as sp


@dataclass
class Counters:
    """Work done on a system: the one list of work counters (:class:`~mslab.trajectory.Stats` reuses it).

    Attributes
    ----------
    n_force : int
        Force evaluations (``System.rhs`` / ``System.acceleration``).
    n_jac : int
        Jacobian assemblies (``System.jacobians``).
    n_solve : int
        Linear solves with a Newton (or other implicit) matrix.
    n_iter : int
        Iterations of implicit solvers (Newton, fixed point).
    n_factor : int
        Matrix factorisations (a solve may reuse an earlier one).
    n_lin_iter : int
        Iterations of iterative linear solvers (conjugate gradients).
    """

    n_force: int = 0
    n_jac: int = 0
    n_solve: int = 0
    n_iter: int = 0
    n_factor: int = 0
    n_lin_iter: int = 0

    def snapshot(self) -> dict:
        """Return the counters as a dict."""
        return {name: getattr(self, name) for name in _COUNTERS}

    def since(self, before: dict) -> dict:
        """Return the work done since ``before`` (a :meth:`snapshot`)."""
        return {k: v - before[k] for k, v in self.snapshot().items()}


#: the counters' names (a session reads them several times per call: fields() each time cost
#: about 5 us)
_COUNTERS = tuple(f.name for f in fields(Counters))


class System:
    """A mass-spring system: who moves, how heavy, and which forces act.

    Parameters
    ----------
    mass : ndarray, shape (n_particles,)
        Particle masses (> 0).
    pinned : ndarray of bool, shape (n_particles,)
        Pinned particles have ``inv_mass = 0``: no force moves them.
    effects : sequence of Effect
        Exactly the force terms of the scene; nothing else is evaluated.
    dim : int
        Space dimension (1, 2 or 3).

    Attributes
    ----------
    velocity_dependent : bool
        Some effect depends on v (damping, damped springs, friction).
    dissipative : bool
        Some effect dissipates energy.
    driving : bool
        Some effect puts in external work (wind): the ledger's ``external`` column.
    counters : Counters
    """

    #: the effects' method that gives their Jacobians (the compiled view of mslab.fast.newton
    #: names their compiled loops)
    _jacobians = "jacobians"

    def __init__(self, mass: npt.ArrayLike, pinned: npt.ArrayLike, effects: Iterable[Effect], dim: int):
        self.mass = np.asarray(mass, dtype=float)
        self.pinned = np.asarray(pinned, dtype=bool)
        self.inv_mass = np.where(self.pinned, 0.0, 1.0 / self.mass)
        self.effects: tuple[Effect, ...] = tuple(effects)
        self.dim = int(dim)
        self.n_particles = self.mass.shape[0]
        self.velocity_dependent = any(e.velocity_dependent for e in self.effects)
        self.dissipative = any(e.dissipative for e in self.effects)
        self.driving = any(e.driving for e in self.effects)
        self.counters = Counters()
        self._inv_mass_col = self.inv_mass[:, None]

    # -- forces -------------------------------------------------------------------
    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Total force on every particle, shape (n_particles, dim). Not counted."""
        f = np.zeros_like(x)
        for e in self.effects:
            f += e.force(x, v)
        return f

    def acceleration(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return ``a = M^-1 sum_e f_e(x, v)``, shape (n_particles, dim). Counts one n_force."""
        self.counters.n_force += 1
        return self._inv_mass_col * self.force(x, v)

    def rhs(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Acceleration and dissipated power in one pass. Counts one n_force.

        The power lets each integrator book the dissipated energy with its own
        quadrature, so the energy ledger is as accurate as the method.
        """
        self.counters.n_force += 1
        if not self.dissipative:
            return self._inv_mass_col * self.force(x, v), 0.0
        f = np.zeros_like(x)
        power = 0.0
        for e in self.effects:
            fe, pe = e.force_and_power(x, v)
            f += fe
            power += pe
        return self._inv_mass_col * f, power

    # -- Jacobians ----------------------------------------------------------------
    def jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix | None]:
        """``(K, D) = (df/dx, df/dv)`` summed over effects, sparse (n*dim, n*dim).

        ``D`` is None when no effect depends on velocity. Counts one n_jac.
        """
        import scipy.sparse as sp

        stiff, damp = self.jacobian_terms(x, v)
        size = self.n_particles * self.dim
        K = sum(stiff[1:], stiff[0]) if stiff else sp.csr_matrix((size, size))
        return K, (sum(damp[1:], damp[0]) if damp else None)

    def jacobian_terms(self, x: np.ndarray, v: np.ndarray) -> tuple[list, list]:
        """Each effect's ``df/dx`` and ``df/dv`` (CSR), unsummed: two lists, absent terms left out.

        Newton's linear solver sums them into its own kept pattern
        (:mod:`mslab.integrators.newton.newton_matrix`). Counts one n_jac.
        """
        self.counters.n_jac += 1
        stiff, damp = [], []
        for e in self.effects:
            kx, kv = getattr(e, self._jacobians)(x, v)
            if kx is not None:
                stiff.append(kx.tocsr())
            if kv is not None:
                damp.append(kv.tocsr())
        return stiff, damp

    @property
    def inv_mass_diag(self) -> sp.dia_matrix:
        """``M^-1`` as a sparse diagonal of size n*dim (0 on pinned particles)."""
        import scipy.sparse as sp

        return sp.diags(np.repeat(self.inv_mass, self.dim))

    # -- energy -------------------------------------------------------------------
    def kinetic_energy(self, v: np.ndarray, compiled: bool = False) -> float:
        """``K = sum_i m_i |v_i|^2 / 2`` over free particles.

        ``compiled``: :func:`kinetic_kernel` (the ledger check of a compiled run: one pass, where
        numpy's masked copies took 86 us on a 64 x 64 cloth; round-off apart the same). Saved
        samples always use the numpy sum.
        """
        from mslab.jit import available

        if compiled and available():
            from mslab.jit import compiled as compile_kernel

            v = np.ascontiguousarray(v, dtype=float)
            return float(compile_kernel(kinetic_kernel)(v, self.mass, self.pinned))
        free = ~self.pinned
        return float(0.5 * np.sum(self.mass[free, None] * v[free] ** 2))

    def kinetic_energies(self, vs: np.ndarray) -> np.ndarray:
        """:meth:`kinetic_energy` of each state of ``vs`` (k, n, dim), bitwise (one numpy sum per state)."""
        free = ~self.pinned
        return 0.5 * state_sums(self.mass[free, None] * vs[:, free] ** 2)

    def potential_energies(self, xs: np.ndarray) -> np.ndarray:
        """:meth:`potential_energy` of each state of ``xs`` (k, n, dim), bitwise (effects' ``energies``)."""
        total = np.zeros(len(xs))
        for e in self.effects:
            if e.conservative:
                total = total + e.energies(xs)
        return total

    def potential_energy(self, x: np.ndarray, compiled: bool = False) -> float:
        """Sum of the potential energies of the conservative effects.

        ``compiled``: each effect's ``compiled_energy`` (the ledger check of a compiled run;
        round-off apart the same). Saved samples always use the numpy ``energy``.
        """
        return float(sum(e.compiled_energy(x) if compiled else e.energy(x)
                         for e in self.effects if e.conservative))

    def dissipated_power(self, x: np.ndarray, v: np.ndarray) -> float:
        """Power (>= 0) removed by dissipative effects at (x, v). Not counted."""
        return float(sum(e.power(x, v) for e in self.effects if e.dissipative))

    def external_work(self, x: np.ndarray, x0: np.ndarray) -> float:
        """Work external drives (wind) put in while the particles moved from ``x0`` to ``x``. Not counted."""
        return float(sum(e.external_work(x, x0) for e in self.effects if e.driving))

    def effect_names(self) -> list[str]:
        """Return the names of the scene's effects, in summation order."""
        return [e.name for e in self.effects]

    def __repr__(self) -> str:
        return (f"System(n_particles={self.n_particles}, dim={self.dim}, "
                f"effects={self.effect_names()})")


def kinetic_kernel(v: np.ndarray, mass: np.ndarray, pinned: np.ndarray) -> float:
    """Return ``sum_i m_i |v_i|^2 / 2`` over the particles not ``pinned``, in particle order.

    The compiled kinetic energy of :meth:`System.kinetic_energy` for the ledger check (its sum
    runs particle by particle, numpy's pairwise: they differ by round-off). Cost ``O(n dim)``.
    """
    total = 0.0
    for p in range(v.shape[0]):
        if not pinned[p]:
            speed2 = 0.0
            for c in range(v.shape[1]):
                speed2 += v[p, c] * v[p, c]
            total += mass[p] * speed2
    return 0.5 * total
