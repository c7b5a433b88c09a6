"""The ledger check of a compiled run sums the springs' energy compiled: numpy's to round-off."""

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
