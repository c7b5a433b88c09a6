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
#: coordinates per chunk of samples whose energies are computed at once (the springs' terms of a
#: chunk then take about 6 x 8 bytes per coordinate: 12 MB)
CHUNK_ENTRIES = 2**18


def xs_bytes(shape: tuple) -> int:
    """Bytes of one float64 array of ``shape`` (the saved positions; velocities the same)."""
    return int(np.prod(shape, dtype=np.float64)) * 8


def physical_memory() -> float:
    """Bytes of this machine's memory (``inf`` where the platform does not say)."""
    import os

    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return float("inf")


def refuse_beyond_memory(n: int, shape: tuple, what: str = "t_end, save_every",
                         fix: str = "a shorter t_end") -> None:
    """ValueError when ``n`` saved samples of ``shape`` could never fit this machine's memory.

    Checked before any array exists: such an allocation may succeed on an overcommitting OS and
    then end the process when it is filled, with no message (a run must fail in one line).
    ``what`` and ``fix`` name the arguments (a declared ``t_end``; an open-ended session's
    :meth:`~mslab.simulation.Simulation.advance`).
    """
    need = n * (2 * xs_bytes(shape) + 7 * 8)  # positions, velocities; steps, d, K, U, W_ext, marks
    if need > physical_memory():
        raise ValueError(f"{what}: the {n:.3g} saved samples would need {need / 2**30:.3g} GiB, "
                         f"more than this machine's {physical_memory() / 2**30:.3g} GiB; use a larger "
                         f"save_every or {fix}")


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
            refuse_beyond_memory(end // save_every + 2, shape)
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

    def refuse_beyond(self, stop: int) -> None:
        """ValueError, before any step, when an open-ended session's samples up to ``stop`` cannot fit."""
        if self.end is None and self.steps[-1] < stop:
            refuse_beyond_memory(stop // self.save_every + 2, self.shape, "advance, save_every",
                                 "fewer steps per session")

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
        chunk = max(1, CHUNK_ENTRIES // max(1, self.x[0].size))
        for lo in range(self._filled, k, chunk):  # the states of a chunk at once, bitwise one by one
            hi = min(k, lo + chunk)
            self._kinetic[lo:hi] = system.kinetic_energies(self.v[lo:hi])
            self._potential[lo:hi] = system.potential_energies(self.x[lo:hi])
        if system.driving:
            for i in range(self._filled, k):
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


#: at most this many energy groups are judged apart (more components are pooled round-robin:
#: each group costs one potential-energy evaluation per ledger check)
MAX_GROUPS = 8


def energy_groups(scene: Scene) -> np.ndarray | None:
    """Return a group label per particle: the particles no effect couples are judged apart.

    Two particles are coupled when an effect joins them: a spring's pair (its damping acts
    along the same pair), else a Jacobian block (``df_i/dx_j`` or ``df_i/dv_j``) at the initial
    state; gravity, drag and colliders (``constant_force``, ``linear_drag``, ``outline``) act
    on each particle alone. No energy flows between groups: each group's ledger is constant
    for the exact motion on its own. Connected components, pooled round-robin into
    :data:`MAX_GROUPS`. None: one group (or an effect without Jacobians).
    """
    system, x0, v0 = scene.system, scene.state0.x, scene.state0.v
    n, dim = system.n_particles, system.dim
    rows, cols = [np.arange(n)], [np.arange(n)]
    for effect in system.effects:
        springs = effect.hooke_springs()
        if springs is not None:
            rows.append(np.asarray(springs.i))
            cols.append(np.asarray(springs.j))
            continue
        if (effect.constant_force() is not None or effect.linear_drag() is not None
                or effect.outline() is not None):
            continue
        try:
            blocks = effect.jacobians(x0, v0)
        except NotImplementedError:
            return None
        for block in blocks:
            if block is not None:
                coo = block.tocoo()
                rows.append(coo.row // dim)
                cols.append(coo.col // dim)
    labels = _components(n, np.concatenate(rows), np.concatenate(cols))
    return None if labels.max() == 0 else labels % MAX_GROUPS


def _components(n: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Return the connected component (0, 1, ...) of each of ``n`` nodes joined by the edges ``(i, j)``.

    Hooking every edge's larger root onto its smaller one, then pointer jumping, until no
    edge joins two roots (numpy only: no scipy import for the common scene).
    """
    root = np.arange(n)
    while True:
        ri, rj = root[i], root[j]
        if np.array_equal(ri, rj):
            break
        low = np.minimum(ri, rj)
        np.minimum.at(root, ri, low)
        np.minimum.at(root, rj, low)
        while True:
            jumped = root[root]
            if np.array_equal(jumped, root):
                break
            root = jumped
    return np.unique(root, return_inverse=True)[1]


def group_scales(scene: Scene, labels: np.ndarray) -> np.ndarray:
    """Return each group's energy scale: :func:`initial_energy_scale` of its own particles.

    ``K0 + sum_fields m |g| L`` of the group (``L = 1 + max |x0|`` over it), plus its mass
    share of the other effects' ``|U0|`` (springs, contacts: not split by particle).
    """
    system, x0, v0 = scene.system, scene.state0.x, scene.state0.v
    free = ~system.pinned
    total_mass = float(np.sum(system.mass[free])) or 1.0
    u0 = abs(sum(float(e.energy(x0)) for e in system.effects  # fields' energy is in `drop`
                 if e.conservative and not hasattr(e, "releasable_energy")))
    scales = np.zeros(int(labels.max()) + 1)
    for g in range(scales.size):
        mine = labels == g
        size = 1.0 + float(np.max(np.abs(x0[mine]))) if mine.any() else 1.0
        movable = mine & free
        drop = sum(float(e.releasable_energy(movable, size)) for e in system.effects
                   if hasattr(e, "releasable_energy"))
        share = float(np.sum(system.mass[movable])) / total_mass
        scales[g] = float(0.5 * np.sum(system.mass[movable, None] * v0[movable] ** 2)) + drop + share * u0
    return scales


def group_ledgers(system: System, labels: np.ndarray, x: np.ndarray, v: np.ndarray,
                  x0: np.ndarray) -> np.ndarray:
    """Return ``K + (U - U(x0)) - W_ext`` of each group (the others held at ``x0``).

    Groups exchange no energy, so each is constant for the exact motion up to the work its
    dissipation removed (the dissipated work is integrated for the whole scene, not per group:
    a group's ledger can only fall by it, and only gains count).
    """
    free = ~system.pinned
    u_start = system.potential_energy(x0)
    out = np.zeros(int(labels.max()) + 1)
    for g in range(out.size):
        mine = labels == g
        mixed = x0.copy()
        mixed[mine] = x[mine]
        kinetic = float(0.5 * np.sum(system.mass[mine & free, None] * v[mine & free] ** 2))
        out[g] = kinetic + system.potential_energy(mixed) - u_start
        if system.driving:
            out[g] -= system.external_work(mixed, x0)
    return out
