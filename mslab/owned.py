"""What a stepping session hands out of its own: read-only attributes and read-only arrays.

A session (:class:`mslab.simulation.Simulation`) steps private copies of the scene's system
and of the method. It hands them out (``sim.system``, ``sim.integrator``) for reading: their
public arrays are read-only views, so an in-place edit (``sim.system.effects[0].stiffness[:] =
...``, ``sim.integrator.b[:] = ...``) raises numpy's "assignment destination is read-only"
ValueError instead of changing the run on one backend and not on the other. The session's own
settings are read-only properties (:func:`read_only`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from mslab.trajectory import Energy, Trajectory

if TYPE_CHECKING:
    from mslab.ledger import Samples
    from mslab.trajectory import Stats


def read_only(name: str, doc: str) -> property:
    """Return a property reading ``self._<name>``, with no setter (rebinding raises AttributeError)."""
    return property(lambda self: getattr(self, "_" + name), doc=doc)


def read_only_arrays(*objects: Any) -> None:
    """Replace each public array attribute of ``objects`` by a read-only view of it.

    The view reads the same memory (the same numbers, bit for bit); code that holds the array
    itself (a compiled loop's parameters, taken when the session started) keeps it. Private
    attributes (a leading underscore: caches, work buffers the library writes) are left alone.
    """
    for obj in objects:
        attributes = getattr(obj, "__dict__", {})
        for name, value in list(attributes.items()):
            if not name.startswith("_") and isinstance(value, np.ndarray) and value.flags.writeable:
                attributes[name] = read_only_view(value)


def read_only_view(array: np.ndarray) -> np.ndarray:
    """Return a view of ``array`` that cannot be written (the same memory)."""
    view = array.view()
    view.flags.writeable = False
    return view


def samples_trajectory(samples: Samples, loop: Any, stats: Stats, dt: float, name: str, k: int,
                       complete: bool, current: bool, handover: bool) -> Trajectory:
    """Return a session's saved samples ``[0, k)`` as a Trajectory.

    The current state is added when ``current`` and it is not saved.
    A part of the store is copied. The whole store of a finished declared run is not (memory
    budget: 1 x): ``handover`` gives its arrays themselves (``simulate``, which drops the
    session), else read-only views, so what one reader edits never reaches the next.
    """
    t = samples.steps[:k] * dt
    if current and samples.steps[k - 1] != loop.step:
        x, v = loop.x, loop.v
        point = samples.point(x, v, loop.dissipated)
        energy = samples.energy(k, copy=False)
        parts = [np.append(p, q) for p, q in zip(
            (energy.kinetic, energy.potential, energy.dissipated, energy.external), point, strict=True)]
        return Trajectory(np.append(t, loop.step * dt), np.concatenate((samples.x[:k], x[None])),
                          np.concatenate((samples.v[:k], v[None])), Energy(*parts), stats, complete, name)
    if k == samples.steps.size:  # the whole declared run
        energy = samples.energy(k, copy=False)
        if handover:
            return Trajectory(t, samples.x, samples.v, energy, stats, complete, name)
        parts = (energy.kinetic, energy.potential, energy.dissipated, energy.external)
        return Trajectory(t, read_only_view(samples.x), read_only_view(samples.v),
                          Energy(*map(read_only_view, parts)), stats, complete, name)
    return Trajectory(t, samples.x[:k].copy(), samples.v[:k].copy(), samples.energy(k, copy=True), stats,
                      complete, name)
