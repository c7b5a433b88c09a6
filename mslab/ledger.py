"""Saved samples of a stepping session and their energy ledger, computed per sample on demand.

The stepping loops (numpy or compiled) store each saved state's positions, velocities and
dissipated work ``D`` (integrated by the method) into a :class:`Samples`; the rest of the
ledger — kinetic energy ``K``, potential energy ``U`` and the external work ``W_ext`` of
drives — is computed from the stored state by the effects' own numpy code when it is first
needed (the saturation check, or the trajectory), once per sample. A call that saves no
sample costs the ledger nothing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.steps import save_indices
from mslab.trajectory import Energy

if TYPE_CHECKING:
    from mslab.scene import Scene
    from mslab.system import System

#: slots of a session of unknown length allocated at first (then doubled as needed)
FIRST_CAPACITY = 8
#: ``save_every`` of an open-ended session that saves only its first state (the default)
NEVER = 2**40


def xs_bytes(shape: tuple) -> int:
    """Bytes of one float64 array of ``shape`` (the saved positions; velocities the same)."""
    return int(np.prod(shape, dtype=np.float64)) * 8


class Samples:
    """The saved states of a session: step ``s`` is saved when ``s % save_every == 0``, and at ``end``.

    Attributes
    ----------
    steps : ndarray of int64, shape (capacity,)
        The step of each slot (the compiled loops' ``saved`` array).
    x, v : ndarray, shape (capacity, n_particles, dim)
    d : ndarray, shape (capacity,)
        Dissipated work at each saved state.
    k : int
        Slots ``[0, k)`` are filled.
    marks : list
        ``(stepping seconds, counters)`` of the session when each sample was saved: where a
        run reported as stopped at that sample stops.
    """

    def __init__(self, system: System, shape: tuple, save_every: int, end: int | None):
        self.system, self.save_every, self.end = system, save_every, end
        self.shape = shape
        self.k = 0
        self.marks: list = []
        self._filled = 0  # samples [0, _filled) have K, U, W_ext
        if end is not None:
            steps = save_indices(end, save_every)
        else:
            steps = np.arange(2 if save_every >= NEVER else FIRST_CAPACITY, dtype=np.int64) * save_every
        self._allocate(steps)

    def _allocate(self, steps: np.ndarray) -> None:
        n = steps.size
        full = (n,) + self.shape
        try:
            x, v = np.empty(full), np.empty(full)
        except MemoryError:
            raise MemoryError(f"the {n} saved samples need {2 * xs_bytes(full) / 2**30:.3g} GiB; "
                              f"use a larger save_every or a shorter t_end") from None
        arrays = (x, v, np.empty(n), np.empty(n), np.empty(n), np.zeros(n))
        if self.k:
            old = (self.x, self.v, self.d, self._kinetic, self._potential, self._external)
            for new, have in zip(arrays, old, strict=True):
                new[: self.k] = have[: self.k]
        self.steps = steps
        self.x, self.v, self.d, self._kinetic, self._potential, self._external = arrays

    def reserve(self, stop: int) -> None:
        """Make room for every sample up to step ``stop`` (a session of unknown length grows)."""
        if self.end is not None or self.steps[-1] >= stop:
            return
        n = max(2 * self.steps.size, stop // self.save_every + 1)
        self._allocate(np.arange(n, dtype=np.int64) * self.save_every)

    def add(self, x: np.ndarray, v: np.ndarray, dissipated: float, mark: tuple) -> None:
        """Store the next sample (the numpy loop)."""
        k = self.k
        self.x[k], self.v[k], self.d[k] = x, v, dissipated
        self.marks.append(mark)
        self.k = k + 1

    def energies(self, k: int) -> None:
        """Compute ``K, U, W_ext`` of the samples ``[0, k)`` not done yet (the effects' own energies)."""
        system = self.system
        for i in range(self._filled, k):
            self._kinetic[i] = system.kinetic_energy(self.v[i])
            self._potential[i] = system.potential_energy(self.x[i])
            if system.driving:
                self._external[i] = system.external_work(self.x[i], self.x[0])
        self._filled = max(self._filled, k)

    def energy(self, k: int, copy: bool) -> Energy:
        """Return the ledger of samples ``[0, k)`` (views of the store unless ``copy``)."""
        self.energies(k)
        parts = (self._kinetic, self._potential, self.d, self._external)
        return Energy(*(p[:k].copy() if copy else p[:k] for p in parts))

    def point(self, x: np.ndarray, v: np.ndarray, dissipated: float) -> tuple[float, float, float, float]:
        """Ledger entries ``(K, U, D, W_ext)`` of a state that is not stored (a session's current state)."""
        system = self.system
        external = system.external_work(x, self.x[0]) if system.driving else 0.0
        return (float(system.kinetic_energy(v)), float(system.potential_energy(x)), float(dissipated),
                float(external))


def initial_energy_scale(scene: Scene) -> float:
    """Return an energy the scene's physics can never exceed by orders of magnitude, from the start.

    ``K0 + |U0| + sum_fields m |g| L`` with ``L = 1 + max |x0|`` (the scene's size seen
    from the origin, where colliders usually sit): the initial kinetic and potential
    energy plus what uniform fields (gravity, declaring ``releasable_energy``) can release
    over that height. Computed from the initial state only, so a blow-up cannot inflate it.
    0 for a scene at rest with nothing to release.
    """
    system, x0, v0 = scene.system, scene.state0.x, scene.state0.v
    size = 1.0 + float(np.max(np.abs(x0)))
    movable = ~system.pinned
    drop = sum(float(e.releasable_energy(movable, size)) for e in system.effects
               if hasattr(e, "releasable_energy"))
    return system.kinetic_energy(v0) + abs(system.potential_energy(x0)) + drop
