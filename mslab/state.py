"""The state of a mass-spring system: positions and velocities of every particle."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class State:
    """Positions and velocities of all particles at one instant.

    Parameters
    ----------
    x : ndarray, shape (n_particles, dim)
        Positions.
    v : ndarray, shape (n_particles, dim)
        Velocities.
    memory : tuple of ndarray, optional
        What a multistep method carries from one step to the next (Verlet: the
        previous positions; leapfrog: the staggered half-step velocity). Empty for
        one-step methods. Integrators create it in ``start`` and read it in ``step``.
    dissipated : float
        Work removed so far by dissipative effects (drag, spring damping, friction).
        Each integrator integrates it alongside x and v with its own quadrature, so the
        energy ledger ``K + U + dissipated`` is conserved to the method's order.

    A ``State`` is never modified in place: integrators return a new one.
    """

    x: np.ndarray
    v: np.ndarray
    memory: tuple = field(default=(), compare=False)
    dissipated: float = 0.0

    @property
    def n_particles(self) -> int:
        """Number of particles."""
        return self.x.shape[0]

    @property
    def dim(self) -> int:
        """Number of space dimensions."""
        return self.x.shape[1]

    def __repr__(self) -> str:
        """Return a one-line summary (sizes, memory, dissipated work), never the arrays."""
        shape = "x".join(str(d) for d in np.shape(self.x))
        memory = f", memory of {len(self.memory)} arrays" if self.memory else ""
        work = self.dissipated
        shown = f"{work:.6g}" if isinstance(work, float | int | np.floating) else type(work).__name__
        return f"State(x and v: {shape}{memory}, dissipated={shown})"

    def is_finite(self) -> bool:
        """Return True when every position and velocity is a finite number."""
        return bool(np.isfinite(self.x).all() and np.isfinite(self.v).all())
