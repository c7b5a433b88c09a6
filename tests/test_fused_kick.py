"""The springs' kick twin: the kick pass inside the springs' second phase gives the same bits.

:func:`mslab.effects.spring_kick.spring_kernel_kick` kicks each block of particles in the
springs' second parallel phase, as soon as the block's forces are complete; the loops use it
on more than one thread (``scene_forces_kick`` in :mod:`mslab.fast.compose`). On one thread the
same compiled loop takes the kernel and the pass apart, the code before the twin: so a run on
two threads against the same run on one checks the twin against the pass apart, bitwise
(states, dissipated energy, the step, message and state of a blow-up), in one compiled module
(``tests/test_float32.py`` does the same for float32 on the 180 x 180 cloth).
"""

from __future__ import annotations

import numpy as np
import pytest

import mslab
from mslab.effects import Springs, spring_batches
from mslab.errors import InstabilityError
from mslab.fast import compose
from mslab.scenes import SceneBuilder, generators

pytest.importorskip("numba")

#: the smallest square cloth whose springs run in two parallel phases (165 x 165: 161,702 springs)
N = 165


def cloth(damped: bool) -> mslab.Scene:
    return generators.cloth(N, N, size=0.02 * (N - 1), mass=0.25 * N * N, structural=1000.0, shear=1000.0,
                            bend=1000.0, damping=10.0 if damped else 0.0)


def session(scene, method: str, dt: float, threads: int):
    assert compose.FUSED_KICK
    return mslab.Simulation(scene, method, dt, backend="numba", check_stability=False, threads=threads)


@pytest.mark.parametrize("damped, method, blocks", [
    (True, "symplectic_euler", None), (True, "symplectic_euler_x", None), (False, "forest_ruth", None),
    (False, "yoshida6", 5), (True, "symplectic_euler", 4), (True, "symplectic_euler", 7)])
def test_the_kick_twin_gives_the_bits_of_the_pass_apart(damped, method, blocks, monkeypatch):
    """Every method whose kicks are plain (velocity Verlet reuses its last kick's acceleration
    and takes no plain kick; damped Forest-Ruth's kicks have stages), 32 blocks and odd or
    small counts (4, 5, 7: the last odd batch kicks one block or two)."""
    if blocks is not None:
        monkeypatch.setattr(spring_batches, "MAX_BLOCKS", blocks)
    scene = cloth(damped)
    springs = next(e for e in scene.system.effects if isinstance(e, Springs))
    phases = springs.kernel_params()[9]
    assert phases.size == 4 and phases[1] - phases[0] > 1  # two parallel phases: the twin kicks
    assert phases[2] == (blocks or spring_batches.MAX_BLOCKS)
    apart = session(scene, method, 1 / 960, threads=1)
    apart.advance(24)
    fused = session(scene, method, 1 / 960, threads=2)
    for _ in range(3):
        fused.advance(8)
    np.testing.assert_array_equal(fused.state.x, apart.state.x)
    np.testing.assert_array_equal(fused.state.v, apart.state.v)
    assert fused.state.dissipated == apart.state.dissipated
    assert np.abs(apart.state.x - scene.state0.x).max() > 0  # it moved


def test_a_blow_up_stops_at_the_same_step_with_the_twin():
    """The blow-up test counts bad entries in the twin's blocks as in the pass apart."""
    scene = cloth(True)
    stops = []
    for threads in (1, 2):
        sim = session(scene, "symplectic_euler", 1 / 20, threads=threads)
        with pytest.raises(InstabilityError) as err:
            sim.advance(400)
        stops.append((err.value.step, str(err.value), sim.state.x.tobytes(), sim.state.v.tobytes()))
    assert stops[0] == stops[1] and stops[0][0] < 400


def test_springs_with_a_far_batch_keep_the_pass_apart():
    """Springs joining far-apart particle numbers (a far batch, summed after the second phase)
    change forces after it: the twin declines and the loop runs the pass, the same bits."""
    springs = next(e for e in cloth(True).system.effects if isinstance(e, Springs))
    b = SceneBuilder(3)
    b.add_particles(cloth(True).state0.x, mass=0.25)
    b.pin(0)
    b.add_springs(np.stack([springs.i, springs.j], 1), stiffness=1000.0, damping=10.0)
    b.add_springs([[0, N * N - 1], [5, N * N // 2]], stiffness=10.0)  # far apart in number
    b.add_gravity([0.0, 0.0, -9.81])
    scene = b.build()
    springs = next(e for e in scene.system.effects if isinstance(e, Springs))
    i, *_, batches, phases, _ = springs.kernel_params()
    assert batches[phases[2] + 1] > batches[phases[2]]  # a far batch
    apart = session(scene, "symplectic_euler", 1 / 960, threads=1)
    fused = session(scene, "symplectic_euler", 1 / 960, threads=2)
    apart.advance(16)
    fused.advance(16)
    np.testing.assert_array_equal(fused.state.x, apart.state.x)
    np.testing.assert_array_equal(fused.state.v, apart.state.v)
