"""The check of a scene's initial state, run before a session does any work.

A scene made with ``dataclasses.replace(scene, state0=...)`` skips the builders' checks; a
session runs these (cheap: one pass over the arrays) before copying the scene. Each refusal
is one error naming ``state0.x`` or ``state0.v``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from mslab.scene import Scene


def check_initial_state(scene: Scene) -> None:
    """Refuse an initial state that is not a float array per particle, not finite, or moves a pin.

    TypeError: ``state0.x`` / ``state0.v`` not a numpy array of real floats. ValueError: a
    shape other than ``(n_particles, dim)``; NaN or inf; a pinned particle (inverse mass 0)
    with a nonzero velocity (no method moves a pin: its velocity must be 0, not zeroed here).
    """
    system, state0 = scene.system, scene.state0
    shape = (system.n_particles, system.dim)
    for name, what in (("x", "positions"), ("v", "velocities")):
        values = getattr(state0, name, None)
        if not isinstance(values, np.ndarray) or values.dtype.kind != "f":
            got = (f"an array of {values.dtype}" if isinstance(values, np.ndarray)
                   else type(values).__name__)
            raise TypeError(f"state0.{name} ({what}) must be a numpy array of floats, got {got}")
        if values.shape != shape:
            raise ValueError(f"state0.{name} ({what}) must have shape {shape} (particles, dim) for "
                             f"this scene, got {values.shape}")
        bad = ~np.all(np.isfinite(values), axis=-1)
        if bad.any():  # before any work: a run from NaN "blows up" at step 1
            raise ValueError(f"initial state: {what} are not finite (NaN or inf) at particles "
                             f"{np.flatnonzero(bad)[:5].tolist()} (state0.{name})")
    moving = (np.asarray(system.inv_mass) == 0) & np.any(state0.v != 0, axis=-1)
    if moving.any():
        first = int(np.flatnonzero(moving)[0])
        raise ValueError(f"state0.v: pinned particle {first} (inverse mass 0) has velocity "
                         f"{state0.v[first].tolist()}, but a pinned particle never moves: set its "
                         f"velocity to 0 (pinned particles with a velocity: "
                         f"{np.flatnonzero(moving)[:5].tolist()})")
