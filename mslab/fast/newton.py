"""The compiled path of the implicit methods: the same Newton code over compiled force and Jacobian loops.

An implicit step is a Newton iteration whose linear algebra (CHOLMOD, SuperLU, LAPACK) is
compiled library code called from Python, between force and Jacobian evaluations. Its
numba path is therefore not a loop of its own: it is the generic code of
:mod:`mslab.integrators.newton.solvers` and :mod:`mslab.integrators.newton.linear` stepping a
:class:`CompiledSystem`, a view of the scene's :class:`~mslab.system.System` whose forces
come from the effects' compiled kernels (:class:`~mslab.fast.model.ForceModel`) and whose
Jacobians come from the effects' ``compiled_jacobians`` (a compiled loop for springs, the
numpy code for effects whose Jacobians cost little). Same counters, same decisions, the
same results to round-off (``tests/test_fast_newton.py``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.system import System

if TYPE_CHECKING:
    from mslab.fast.model import ForceModel
    from mslab.fast.newton_assembly import CompiledNewtonMatrix


class CompiledSystem(System):
    """A view of ``system`` (same masses, effects and counters) evaluated by compiled loops.

    Parameters
    ----------
    system : System
        The scene's system; the view shares its arrays, effects and :class:`Counters`.
    model : ForceModel
        The compiled forces of the same effects.
    """

    _jacobians = "compiled_jacobians"

    def __init__(self, system: System, model: ForceModel):
        self.__dict__.update(vars(system))
        self.source = system
        self.model = model

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return the total force from the compiled kernels (not counted, as ``System.force``)."""
        return self.model.force(x, v)[0]

    def acceleration(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return ``M^-1 f`` from the compiled kernels. Counts one n_force."""
        self.counters.n_force += 1
        return self.model.rhs(x, v)[0]

    def rhs(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Acceleration and dissipated power from the compiled kernels. Counts one n_force."""
        self.counters.n_force += 1
        return self.model.rhs(x, v)

    def potential_energy(self, x: np.ndarray) -> float:
        """Return the potential energy, the Hooke springs' part from a compiled loop."""
        from mslab.fast.newton_assembly import hooke_energy

        return hooke_energy(self, x)

    def newton_assembly(self, c: float, free: np.ndarray, clamp: bool = False) -> CompiledNewtonMatrix:
        """Return a :class:`~mslab.fast.newton_assembly.CompiledNewtonMatrix` of this system.

        Newton's matrix ``A = M - c^2 K - c D`` on the free dofs, the springs' terms written
        by a compiled loop straight into its kept pattern (asked for by
        :class:`mslab.integrators.newton.linear.StageSolver`).
        """
        from mslab.fast.newton_assembly import CompiledNewtonMatrix

        return CompiledNewtonMatrix(self, c, free, clamp)

    def warm(self) -> None:
        """Load (or compile) the force and Jacobian loops now, on a zero state (nothing counted)."""
        zero = np.zeros((self.n_particles, self.dim))
        self.model.rhs(zero, zero)
        for e in self.effects:
            e.compiled_jacobians(zero, zero)
        self.potential_energy(zero)
