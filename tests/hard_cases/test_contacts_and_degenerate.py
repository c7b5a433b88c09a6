"""Penalty floor 100x stiffer than the springs; zero rest lengths; nearly coincident particles."""

import numpy as np
import pytest

import mslab
from mslab import stability as st

from .scenes import chain_onto_plane, nearly_coincident, zero_rest_length


def _steps(dt, t_end=1.0):
    n = max(1, round(t_end / dt))
    return n * dt


def test_prediction_includes_the_floor_before_any_contact():
    scene = chain_onto_plane()  # k = 100 springs, floor 1e4, masses 0.1, starting 5 cm above it
    possible = st.max_stable_dt(scene, "verlet")
    active = st.max_stable_dt(scene, "verlet", contacts="active")  # springs only at state0
    w_floor = np.sqrt(1e4 / 0.1)
    w_bound = np.sqrt((1e4 + 4 * 100) / 0.1)  # floor plus at most two springs' 2k each
    assert 2 / w_bound <= possible <= 2 / w_floor
    assert active > 5 * possible


@pytest.mark.parametrize("method", ["rk4", "verlet", "symplectic_euler"])
def test_explicit_through_impacts(method):
    scene = chain_onto_plane()
    limit = st.max_stable_dt(scene, method)
    e0 = abs(mslab.simulate(scene, method, dt=0.25 * limit, t_end=0.25 * limit).energy.total[0])
    fine = mslab.simulate(scene, method, dt=0.25 * limit, t_end=_steps(0.25 * limit), save_every=10)
    assert fine.complete and fine.x[:, :, 1].min() < 0.0  # it did hit the floor
    assert np.max(np.abs(fine.energy.total - fine.energy.total[0])) < 0.25 * e0
    # three times the prediction is still below the springs-only limit, but not the floor's:
    with pytest.warns(mslab.StabilityWarning):
        coarse = mslab.simulate(scene, method, dt=3 * limit, t_end=_steps(3 * limit), save_every=1,
                                energy_blowup=np.inf)
    assert np.max(np.abs(coarse.energy.total - coarse.energy.total[0])) > 5 * e0
    # the impacts gain that energy within a few steps: the ledger check stops the run (it completed
    # before issue 41's impact rule)
    with pytest.warns(mslab.StabilityWarning), pytest.raises(mslab.InstabilityError, match="an impact"):
        mslab.simulate(scene, method, dt=3 * limit, t_end=_steps(3 * limit), save_every=1)


def test_implicit_euler_lands_softly_at_ten_times_the_explicit_limit():
    scene = chain_onto_plane()
    dt = 10 * st.max_stable_dt(scene, "verlet")
    tr = mslab.simulate(scene, "implicit_euler", dt=dt, t_end=_steps(dt))
    energy = tr.energy.kinetic + tr.energy.potential
    assert np.all(np.isfinite(tr.x))
    assert np.all(np.diff(energy) <= 1e-12 * np.max(np.abs(energy)))
    static_depth = 0.1 * 9.81 / 1e4
    assert -tr.x[:, :, 1].min() < 4 * static_depth  # no tunnelling through the floor


@pytest.mark.parametrize("method", ["rk4", "verlet", "implicit_euler", "implicit_midpoint"])
def test_zero_rest_length_spring_through_its_anchor(method):
    """Length 0 twice per period: the force -k d stays linear and the exact solution is a cosine."""
    scene = zero_rest_length()
    w = np.sqrt(100.0)
    dt = 2e-3
    tr = mslab.simulate(scene, method, dt=dt, t_end=0.64, save_every=4)  # one period is 0.628
    assert np.min(np.abs(tr.x[:, 1, 0])) < 0.01  # it passed (close to) the anchor
    exact = 0.3 * np.cos(w * tr.t)
    err = np.max(np.abs(tr.x[:, 1, 0] - exact))
    order = mslab.get_method(method).order
    assert err < 0.3 * 5 * (w * dt) ** order + 1e-9
    assert np.all(tr.x[:, 1, 1] == 0.0)  # the zero-length direction never leaks a sideways force


def test_zero_rest_length_jacobian_at_zero_length_is_minus_k_identity():
    scene = zero_rest_length()
    x = scene.state0.x.copy()
    x[1] = x[0]  # on top of the anchor
    K, D, inv_mass = st.linearise(scene, x=x)
    np.testing.assert_allclose(K.toarray(), -100.0 * np.eye(2))
    assert D is None


@pytest.mark.parametrize("gap", [1e-6, 1e-9, 1e-12])
def test_nearly_coincident_particles_separate_to_the_rest_length(gap):
    scene = nearly_coincident(gap=gap)
    tr = mslab.simulate(scene, "implicit_euler", dt=2e-2, t_end=3.0, save_every=5)
    d = np.linalg.norm(tr.x[:, 1] - tr.x[:, 0], axis=1)
    assert np.all(np.isfinite(tr.x))
    assert 0.05 < d[-1] < 0.15  # settles near rest length 0.1 (implicit Euler damps)
    assert np.allclose(tr.x[:, :, 1], 0.0)  # stays on its line
    assert np.allclose(tr.x.sum(axis=1)[:, 0], gap)  # momentum: the midpoint does not move


def test_nearly_coincident_explicit_predicts_and_bounds():
    scene = nearly_coincident(gap=1e-9)
    limit = st.max_stable_dt(scene, "verlet")
    assert limit == pytest.approx(2 / np.sqrt(2 * 100.0), rel=1e-6)  # relative mode, reduced mass 1/2
    tr = mslab.simulate(scene, "verlet", dt=0.5 * limit, t_end=200 * 0.5 * limit)
    d = np.linalg.norm(tr.x[:, 1] - tr.x[:, 0], axis=1)
    assert np.all(np.isfinite(d)) and d.max() < 0.25
