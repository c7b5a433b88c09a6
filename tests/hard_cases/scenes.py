"""Builders of the hard-case scenes (programmatic: SceneBuilder and the generators)."""

from __future__ import annotations

import numpy as np

import mslab
from mslab.scenes.generators import chain


def stiff_chain(n: int = 6, gamma_per_mass: float = 0.0):
    """A hanging chain with k/m = 1e9 (w_max ~ 6e4 rad/s): explicit limits of some 1e-5 s.

    ``gamma_per_mass``: viscous drag gamma/m (1/s) on every particle (0: undamped).
    """
    return chain(n, dim=2, length=0.5, mass=1e-3 * n, stiffness=1e6, gamma=gamma_per_mass * 1e-3)


def mass_ratio_chain(n: int = 9, ratio: float = 1e4, stiffness: float = 1e4):
    """A chain whose masses alternate between 1 and 1/ratio (a heavy/light mass ratio of 1e4).

    Stiff enough that gravity stretches the springs little: the tension's transverse
    stiffness stays well below k, so the state0 linearisation holds along the run.
    """
    b = mslab.SceneBuilder(2)
    for i in range(n):
        b.add_particle([0.1 * i, 0.0], mass=1.0 if i % 2 == 0 else 1.0 / ratio, pinned=i == 0)
    for i in range(n - 1):
        b.add_spring(i, i + 1, stiffness)
    b.add_gravity([0.0, -9.81])
    return b.build("mass ratio chain", f"masses 1 and {1 / ratio:g}")


def chain_onto_plane(n: int = 5, stiffness: float = 100.0, factor: float = 100.0):
    """A horizontal free chain dropped onto a penalty floor ``factor`` times stiffer than its springs."""
    b = mslab.SceneBuilder(2)
    for i in range(n):
        b.add_particle([0.1 * i, 0.05], mass=0.1)
    for i in range(n - 1):
        b.add_spring(i, i + 1, stiffness)
    b.add_gravity([0.0, -9.81])
    b.add_plane(normal=[0.0, 1.0], offset=0.0, stiffness=factor * stiffness)
    return b.build("chain onto plane", f"floor stiffness {factor:g} x the springs'")


def zero_rest_length(dim: int = 2, stiffness: float = 100.0, mass: float = 1.0):
    """A particle on a zero-rest-length spring to a pinned anchor, passing through the anchor.

    The force ``-k d`` is linear, so ``x(t) = x0 cos(w t) + v0 sin(w t)/w`` exactly, and the
    spring's length goes through 0 twice per period when ``v0`` is parallel to ``x0``.
    """
    b = mslab.SceneBuilder(dim)
    anchor = b.add_particle(np.zeros(dim), mass=mass, pinned=True)
    x0 = np.zeros(dim)
    x0[0] = 0.3
    p = b.add_particle(x0, mass=mass)
    b.add_spring(anchor, p, stiffness, rest_length=0.0)
    return b.build("zero rest length", "spring of rest length 0 through its anchor")


def nearly_coincident(gap: float = 1e-9, rest_length: float = 0.1):
    """Two free particles ``gap`` apart joined by a spring of ``rest_length``: pushed apart hard."""
    b = mslab.SceneBuilder(2)
    i = b.add_particle([0.0, 0.0], mass=1.0)
    j = b.add_particle([gap, 0.0], mass=1.0)
    b.add_spring(i, j, 100.0, rest_length=rest_length)
    return b.build("nearly coincident", f"particles {gap:g} apart, rest length {rest_length:g}")
