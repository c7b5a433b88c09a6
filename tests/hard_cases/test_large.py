"""A 1000-mass chain (Lanczos path of the prediction) and a cloth with bending springs at large dt."""

import numpy as np
import pytest

import mslab
from mslab import stability as st
from mslab.scenes.generators import chain, cloth


@pytest.fixture(scope="module")
def long_chain():
    return chain(1000, dim=2, length=10.0, mass=10.0, stiffness=1e4)


def test_1000_mass_chain_prediction_matches_the_closed_form(long_chain):
    """Fixed-free chain of N free masses: w_j = 2 sqrt(k/m) sin((2j - 1) pi / (2 (2N + 1)))."""
    n_free, k, m = 999, 1e4, 0.01
    w_max = 2 * np.sqrt(k / m) * np.sin((2 * n_free - 1) * np.pi / (2 * (2 * n_free + 1)))
    assert long_chain.system.n_particles * 2 > 600  # beyond the dense path: eigsh
    assert st.max_stable_dt(long_chain, "verlet") == pytest.approx(2 / w_max, rel=1e-6)
    assert st.max_stable_dt(long_chain, "rk4") == pytest.approx(2 * np.sqrt(2) / w_max, rel=1e-6)


def test_1000_mass_chain_runs_at_0_9_and_stops_at_1_5(long_chain):
    limit = st.max_stable_dt(long_chain, "symplectic_euler")
    tr = mslab.simulate(long_chain, "symplectic_euler", dt=0.9 * limit, t_end=1000 * 0.9 * limit,
                        save_every=100)
    assert tr.complete and np.all(np.isfinite(tr.x))
    e = tr.energy
    assert np.max(np.abs(e.total - e.total[0])) < 0.05 * np.max(e.kinetic + np.abs(e.potential))
    with pytest.warns(mslab.StabilityWarning), pytest.raises(mslab.InstabilityError) as info:
        mslab.simulate(long_chain, "symplectic_euler", dt=1.5 * limit, t_end=1000 * 1.5 * limit,
                       save_every=100)
    assert info.value.stable_dt == pytest.approx(limit)


def test_cloth_with_bending_springs_at_large_dt_implicit():
    scene = cloth(8, 8, structural=2000.0, shear=200.0, bend=100.0)
    assert "bend" in set(scene.spring_kind)
    explicit = st.max_stable_dt(scene, "rk4")
    dt = 50 * explicit
    tr = mslab.simulate(scene, "implicit_euler", dt=dt, t_end=40 * dt)
    energy = tr.energy.kinetic + tr.energy.potential
    assert tr.complete and np.all(np.isfinite(tr.x))
    assert np.all(np.diff(energy) <= 1e-12 * np.max(np.abs(energy)))
    lengths = scene.springs().lengths(tr.x[-1])
    assert np.max(lengths / scene.springs().rest_length) < 1.2  # no spring torn apart
