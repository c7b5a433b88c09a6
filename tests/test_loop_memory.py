"""The method's memory a compiled session hands out, and a loop continued from it.

The compiled loops keep the state and the two-step methods' memory in coordinate rows
(``(dim, n)``, :mod:`mslab.fast.loops`); :class:`mslab.fast.runner.Stepper` converts both ways.
Checked against the numpy loop (the reference: the same memory to round-off, in the same
shapes) and against the loop itself (a fresh loop loaded with a handed-out state continues bit
for bit).
"""

from __future__ import annotations

import numpy as np
import pytest

import mslab
from mslab.scenes import generators

pytest.importorskip("numba")
pytestmark = [pytest.mark.filterwarnings("ignore::mslab.StabilityWarning")]

METHODS = ["verlet", "leapfrog", "velocity_verlet", "symplectic_euler", "rk4"]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("dim, gamma", [(3, 0.0), (3, 0.2), (2, 0.0)])
def test_compiled_state_hands_out_the_methods_memory(method, dim, gamma):
    scene = generators.chain(12, dim=dim, gamma=gamma)
    runs = {b: mslab.Simulation(scene, method, dt=1e-3, backend=b) for b in ("numpy", "numba")}
    for sim in runs.values():
        sim.advance(30)
    ref, got = runs["numpy"].state, runs["numba"].state
    assert len(got.memory) == len(ref.memory)
    for m_ref, m_got in zip(ref.memory, got.memory, strict=True):
        assert np.shape(m_got) == np.shape(m_ref)
        if np.ndim(m_ref):  # particle-major float64 copies, like x and v
            assert m_got.dtype == np.float64 and m_got.flags.c_contiguous and m_got.flags.owndata
        scale = max(1.0, float(np.max(np.abs(m_ref))))
        assert np.max(np.abs(np.asarray(m_got) - np.asarray(m_ref))) <= 1e-12 * scale


@pytest.mark.parametrize("method", ["verlet", "leapfrog", "velocity_verlet", "symplectic_euler"])
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_a_loop_loaded_with_a_handed_out_state_continues_bitwise(method, dtype):
    from mslab.fast.runner import Stepper

    scene = generators.cloth(6, 5)
    sim = mslab.Simulation(scene, method, dt=1e-3, backend="numba", dtype=dtype, check_stability=False)
    sim.advance(25)
    state = sim.state
    fresh = Stepper(sim.system, sim.integrator, np.dtype(dtype))
    empty = np.empty((0, scene.n_particles, scene.dim))
    step, _, cont, ok = fresh.advance(state, sim.dt, 25, 45, np.zeros(0, np.int64), 0, empty, empty,
                                      np.empty(0), 1e30)
    sim.advance(20)
    assert ok and step == 45
    after = sim.state
    for a, b in zip((cont.x, cont.v, *cont.memory), (after.x, after.v, *after.memory), strict=True):
        assert np.asarray(a).tobytes() == np.asarray(b).tobytes()
    assert cont.dissipated == after.dissipated
