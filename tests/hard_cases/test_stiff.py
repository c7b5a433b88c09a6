"""Stiff springs (k/m = 1e9) and a mass ratio of 1e4: predicted limits hold, implicit Euler survives."""

import numpy as np
import pytest

import mslab
from mslab import stability as st

from .scenes import mass_ratio_chain, stiff_chain

EXPLICIT = ["rk4", "symplectic_euler", "symplectic_euler_x", "verlet", "leapfrog", "velocity_verlet"]


def _energy_error(tr):
    e = tr.energy
    return float(np.max(np.abs(e.total - e.total[0])) / np.max(e.kinetic + np.abs(e.potential)))


def test_stiff_chain_is_stiff():
    scene = stiff_chain()
    m = scene.system.mass[1]
    assert scene.springs().stiffness[0] / m >= 1e9
    w_max = float(np.max(np.abs(st.eigenvalues(scene))))
    assert 2 * np.sqrt(1e9) * 0.95 < w_max <= 2 * np.sqrt(1e9)  # a chain's top mode: below 2 sqrt(k/m)


def test_implicit_euler_far_beyond_the_explicit_limit():
    scene = stiff_chain()
    explicit = st.max_stable_dt(scene, "rk4")
    dt = 300 * explicit
    tr = mslab.simulate(scene, "implicit_euler", dt=dt, t_end=40 * dt)
    assert tr.complete and np.all(np.isfinite(tr.x)) and np.all(np.isfinite(tr.v))
    energy = tr.energy.kinetic + tr.energy.potential  # no damping: K + U is the total
    assert np.all(np.diff(energy) <= 1e-12 * np.max(np.abs(energy)))  # never increases
    assert energy[-1] < energy[0]
    # and the chain hangs below its pin instead of exploding: every particle within its length
    assert np.max(np.linalg.norm(tr.x[-1] - tr.x[-1][0], axis=1)) < 0.51


@pytest.mark.parametrize("method", EXPLICIT)
def test_explicit_bounded_at_0_9_and_stopped_at_1_5_the_limit(method):
    scene = stiff_chain()
    limit = st.max_stable_dt(scene, method)
    assert 1e-5 < limit < 1e-4
    dt = 0.9 * limit
    tr = mslab.simulate(scene, method, dt=dt, t_end=3000 * dt, save_every=30)
    assert tr.complete and np.all(np.isfinite(tr.x))
    assert _energy_error(tr) < 1e-2
    dt = 1.5 * limit
    with pytest.warns(mslab.StabilityWarning):
        with pytest.raises(mslab.InstabilityError) as info:
            mslab.simulate(scene, method, dt=dt, t_end=3000 * dt, save_every=30)
    err = info.value
    assert err.method == method and err.dt == dt and err.stable_dt == pytest.approx(limit)
    assert np.all(np.isfinite(err.trajectory.x))  # what was kept is finite: never a silent NaN


@pytest.mark.parametrize("method", [
    "euler", "heun", "midpoint", "rk4"])
def test_damped_stiff_chain_for_methods_unstable_without_damping(method):
    """With strong drag the Euler-type methods get a finite limit from the complex eigenvalues."""
    scene = stiff_chain(gamma_per_mass=6e3)
    limit = st.max_stable_dt(scene, method)
    assert limit > 0
    dt = 0.9 * limit
    tr = mslab.simulate(scene, method, dt=dt, t_end=3000 * dt, save_every=30)
    assert tr.complete and _energy_error(tr) < 1e-2
    dt = 1.5 * limit
    with pytest.warns(mslab.StabilityWarning):
        with pytest.raises(mslab.InstabilityError):
            mslab.simulate(scene, method, dt=dt, t_end=40000 * dt, save_every=1000)


@pytest.mark.parametrize("method", ["symplectic_euler", "rk4"])
def test_mass_ratio_1e4(method):
    scene = mass_ratio_chain()
    assert scene.system.mass.max() / scene.system.mass.min() == pytest.approx(1e4)
    limit = st.max_stable_dt(scene, method)
    light = np.sqrt(2 * 1e4 / 1e-4)  # a light mass between two (nearly fixed) heavy ones
    assert limit == pytest.approx(st.oscillator_limit(method) / light, rel=0.02)
    tr = mslab.simulate(scene, method, dt=0.9 * limit, t_end=3000 * 0.9 * limit, save_every=30)
    assert tr.complete and _energy_error(tr) < 0.05
    with pytest.warns(mslab.StabilityWarning), pytest.raises(mslab.InstabilityError):
        mslab.simulate(scene, method, dt=1.5 * limit, t_end=3000 * 1.5 * limit, save_every=30)


def test_mass_ratio_implicit_euler_at_large_dt():
    scene = mass_ratio_chain()
    dt = 100 * st.max_stable_dt(scene, "rk4")
    tr = mslab.simulate(scene, "implicit_euler", dt=dt, t_end=60 * dt)
    energy = tr.energy.kinetic + tr.energy.potential
    assert np.all(np.isfinite(tr.x)) and np.all(np.diff(energy) <= 1e-12 * np.max(np.abs(energy)))


def test_forward_euler_saturated_instability_is_stopped_by_the_ledger():
    """Beyond its limit forward Euler's instability saturates: positions stay bounded, but the
    energy ledger explodes. simulate stops such a run too, naming the energy growth."""
    scene = stiff_chain(gamma_per_mass=6e3)
    limit = st.max_stable_dt(scene, "euler")
    stable = mslab.simulate(scene, "euler", dt=0.9 * limit, t_end=3000 * 0.9 * limit, save_every=30)
    scale = float(np.max(stable.energy.kinetic + np.abs(stable.energy.potential)))
    dt = 1.5 * limit
    with pytest.warns(mslab.StabilityWarning):
        with pytest.raises(mslab.InstabilityError, match="energy ledger") as info:
            mslab.simulate(scene, "euler", dt=dt, t_end=20000 * dt, save_every=1000)
    err = info.value
    assert err.stable_dt == pytest.approx(limit) and err.step > 0
    # the whole run, without the check, shows what it caught: bounded positions, exploded energy
    full = mslab.simulate(scene, "euler", dt=dt, t_end=20000 * dt, save_every=1000,
                          check_stability=False, energy_blowup=np.inf)
    assert np.all(np.isfinite(full.x)) and np.abs(full.x).max() < 10.0
    assert np.max(np.abs(full.energy.total - full.energy.total[0])) > 1e3 * scale
    kept = err.trajectory
    assert kept.t[-1] < err.t and not kept.complete
