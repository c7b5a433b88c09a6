"""The particle passes of the compiled splitting loop on all threads: parts, and the same bits as one part."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import mslab
from mslab.fast import model as fast_model
from mslab.jit import numba
from mslab.scenes import generators

pytestmark = pytest.mark.filterwarnings("ignore::mslab.StabilityWarning")


@given(st.integers(0, 3_000_000))
def test_cuts_cover_the_entries_in_aligned_parts(size):
    cuts = fast_model.particle_cuts(size)
    assert cuts[0] == 0 and cuts[-1] == size and np.all(np.diff(cuts) > 0) | (size == 0)
    if size < fast_model.MIN_ENTRIES_PARALLEL:
        assert cuts.tolist() == [0, size]
    else:
        assert len(cuts) == fast_model.MAX_PARTS + 1
        assert np.all(cuts[:-1] % 16 == 0)  # every part starts on a float32 cache line
        assert np.ptp(np.diff(cuts)) <= 32  # about equal parts


def test_a_300_cloth_steps_its_particles_in_parts():
    """The frame race's biggest cloth (270k entries) is above the threshold; the course's scenes below it."""
    assert 300 * 300 * 3 >= fast_model.MIN_ENTRIES_PARALLEL > 64 * 64 * 3


def run(scene, method, threads, parts, monkeypatch):
    """Return the state and energy ledger of a short compiled run, particle passes in parts or not."""
    monkeypatch.setattr(fast_model, "MIN_ENTRIES_PARALLEL", 0 if parts else 10**12)
    sim = mslab.Simulation(scene, method, dt=2e-4, backend="numba", threads=threads)
    cuts = sim_cuts(sim)
    assert (len(cuts) - 1 == fast_model.MAX_PARTS) if parts else cuts.tolist() == [0, cuts[-1]]
    sim.advance(40)
    return sim.state.x, sim.state.v, sim.trajectory.energy.total


def sim_cuts(sim):
    sim.advance(0)
    return sim._loop.runner.model.cuts


@pytest.mark.parametrize("method, damped", [("symplectic_euler", True), ("symplectic_euler_x", True),
                                            ("forest_ruth", False), ("symplectic_euler", False)])
def test_parts_give_the_bits_of_one_part_on_any_thread_count(method, damped, monkeypatch):
    """Kick, kick keeping a, kick with a known a, drift: 32 parts on 1 and 2 threads give one part's bits."""
    scene = generators.cloth(24, 20, damping=0.5 if damped else 0.0)  # 1440 entries: 32 parts of 32 and 48
    reference = run(scene, method, 1, False, monkeypatch)
    threads = (1, 2) if numba().config.NUMBA_NUM_THREADS >= 2 else (1,)
    for n in threads:
        parted = run(scene, method, n, True, monkeypatch)
        for a, b in zip(reference, parted, strict=True):
            assert np.array_equal(a, b)


def test_the_splitting_loop_compiles_its_particle_pass_parallel(monkeypatch):
    """Above the threshold the pass is numba's parallel loop (the old loop had none: one core did a
    sixth of a 300² step); below it the module has no parallel loop to compile (6-8 s cold)."""
    modules = {}
    for parts in (True, False):
        monkeypatch.setattr(fast_model, "MIN_ENTRIES_PARALLEL", 0 if parts else 10**12)
        sim = mslab.Simulation(generators.cloth(8, 8), "symplectic_euler", backend="numba")
        sim.advance(1)
        modules[parts] = sim._loop.runner.model.module
    assert modules[True] is not modules[False]
    assert modules[True]._particle_pass.targetoptions.get("parallel")
    assert not modules[False]._particle_pass.targetoptions.get("parallel")
    for module in modules.values():
        assert not module.run_splitting.targetoptions.get("parallel")
