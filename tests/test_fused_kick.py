"""The springs' kick twin: the kick pass inside the springs' second phase gives the same bits.

:func:`mslab.effects.spring_kick.spring_kernel_kick` kicks each block of particles in the
springs' second parallel phase, as soon as the block's forces are complete
(``mslab.fast.compose.FUSED_KICK``; on more than one thread). The claim checked here is exact:
states, dissipated energy and the step of a blow-up are bitwise those of the kernel and the
pass apart (the loops before the twin), on one thread and on two, in float64 and float32.
"""

from __future__ import annotations

import numpy as np
import pytest

import mslab
from mslab.effects import Springs
from mslab.errors import InstabilityError
from mslab.fast import compose
from mslab.scenes import generators

pytest.importorskip("numba")

#: the smallest square cloth whose springs run in two parallel phases (165 x 165: 161,702 springs)
N = 165


def cloth(damped: bool) -> mslab.Scene:
    return generators.cloth(N, N, size=0.02 * (N - 1), mass=0.25 * N * N, structural=1000.0, shear=1000.0,
                            bend=1000.0, damping=10.0 if damped else 0.0)


def session(scene, method: str, dt: float, fused: bool, threads: int, dtype: str = "float64"):
    old = compose.FUSED_KICK
    compose.FUSED_KICK = fused
    try:
        return mslab.Simulation(scene, method, dt, backend="numba", check_stability=False, threads=threads,
                                dtype=dtype)
    finally:
        compose.FUSED_KICK = old


@pytest.mark.parametrize("damped, method, dtype", [
    (True, "symplectic_euler", "float64"), (True, "symplectic_euler", "float32"),
    (True, "symplectic_euler_x", "float64"), (False, "forest_ruth", "float64"),
    (False, "velocity_verlet", "float64")])
def test_the_kick_twin_gives_the_bits_of_the_pass_apart(damped, method, dtype):
    scene = cloth(damped)
    springs = next(e for e in scene.system.effects if isinstance(e, Springs))
    phases = springs.kernel_params()[9]
    assert phases.size == 4 and phases[1] - phases[0] > 1  # two parallel phases: the twin kicks
    apart = session(scene, method, 1 / 960, fused=False, threads=1, dtype=dtype)
    apart.advance(24)
    for threads in (1, 2):
        fused = session(scene, method, 1 / 960, fused=True, threads=threads, dtype=dtype)
        for _ in range(3):
            fused.advance(8)
        np.testing.assert_array_equal(fused.state.x, apart.state.x)
        np.testing.assert_array_equal(fused.state.v, apart.state.v)
        assert fused.state.dissipated == apart.state.dissipated
    assert np.abs(apart.state.x - scene.state0.x).max() > 0  # it moved


def test_a_blow_up_stops_at_the_same_step_with_the_twin():
    """The blow-up test counts bad entries in the twin's blocks as in the pass apart."""
    scene = cloth(True)
    steps = []
    for fused in (False, True):
        sim = session(scene, "symplectic_euler", 1 / 20, fused=fused, threads=2)
        with pytest.raises(InstabilityError) as err:
            sim.advance(400)
        steps.append(err.value.step)
    assert steps[0] == steps[1] < 400
