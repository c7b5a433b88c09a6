"""The ledger check of a compiled run sums the springs' and kinetic energy compiled: numpy's to round-off."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mslab
from mslab.effects import Springs
from mslab.scenes import generators


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(1, 3), st.integers(0, 2**32 - 1))
def test_compiled_energy_is_numpys_to_round_off(m, dim, seed):
    """Random springs (some of zero length, some joining a particle to itself): the two sums agree
    within the error model of summing m non-negative terms, m eps sum (numpy's sum is pairwise)."""
    rng = np.random.default_rng(seed)
    n = max(2, m // 2)
    pairs = rng.integers(0, n, (m, 2))
    springs = Springs(pairs, rng.uniform(0.1, 1e4, m), rng.uniform(0.0, 2.0, m), 0.0, n)
    x = rng.normal(0.0, 1.0, (n, dim))
    x[1] = x[0]  # a zero-length spring where the pair (0, 1) occurs
    exact = springs.energy(x)
    assert abs(springs.compiled_energy(x) - exact) <= 4 * m * np.finfo(float).eps * exact


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 400), st.integers(1, 3), st.integers(0, 2**32 - 1))
def test_compiled_kinetic_energy_is_numpys_to_round_off(n, dim, seed):
    """Free particles only (a pinned one moving fast would change the sum: planted below), within
    the model of summing n dim non-negative terms."""
    from mslab.system import System

    rng = np.random.default_rng(seed)
    pinned = rng.random(n) < 0.2
    system = System(rng.uniform(0.01, 10.0, n), pinned, [], dim)
    v = rng.normal(0.0, 1.0, (n, dim))
    exact = system.kinetic_energy(v)
    bound = 4 * n * dim * np.finfo(float).eps * exact
    assert abs(system.kinetic_energy(v, compiled=True) - exact) <= bound
    if pinned.any():
        v[pinned] = 1e3
        assert abs(system.kinetic_energy(v, compiled=True) - exact) <= bound


def test_a_compiled_runs_ledger_check_never_calls_numpys_energy(monkeypatch):
    """The periodic check of a long compiled session uses the compiled sum (numpy's took a sixth of
    the steps between two checks on a 300 x 300 cloth); the checks are the same steps as before."""
    scene = generators.cloth(12, 12, damping=0.5)
    sim = mslab.Simulation(scene, "symplectic_euler", dt=1e-3, backend="numba")
    sim.advance(1)  # the start: the first sample's ledger, numpy's
    calls = {"numpy": 0, "compiled": 0}
    numpy_energy, compiled_energy = Springs.energy, Springs.compiled_energy

    def counted(name, method):
        def wrapper(self, x):
            calls[name] += 1
            return method(self, x)
        return wrapper

    monkeypatch.setattr(Springs, "energy", counted("numpy", numpy_energy))
    monkeypatch.setattr(Springs, "compiled_energy", counted("compiled", compiled_energy))
    sim.advance(1000)
    checks = sum(sim._check.due(step) for step in range(2, 1002))  # steps 2, 4, ..., then every 128
    assert checks >= 10 and calls == {"numpy": 0, "compiled": checks}


@pytest.mark.filterwarnings("ignore::mslab.StabilityWarning")
def test_the_compiled_check_still_stops_an_unstable_run():
    """Forward Euler on an undamped cloth blows up through the ledger check, as on the numpy loop."""
    scene = generators.cloth(10, 10)
    messages = []
    for backend in ("numpy", "numba"):
        with pytest.raises(mslab.InstabilityError) as err:
            mslab.simulate(scene, "euler", t_end=200.0, dt=2e-3, backend=backend)
        messages.append(str(err.value).split(":")[0])
    assert messages[0] == messages[1]
