"""simulate(): long-run energy behaviour, blow-up detection, saving, only declared effects."""

import numpy as np
import pytest

import mslab
from mslab.effects import Damping, Gravity, PenaltyCollider, Plane, Sphere
from mslab.scenes import SceneBuilder, chain, oscillator


def small_chain():
    """An undamped 3-mass chain swinging under gravity (nonlinear), w_max*dt ~ 0.1."""
    return chain(4, dim=2, length=0.6, mass=0.3, stiffness=30.0)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["symplectic_euler", "symplectic_euler_x", "verlet", "leapfrog",
                                    "velocity_verlet", "euler", "implicit_euler"])
def test_energy_over_many_steps(method):
    """Symplectic: 10^5 steps with bounded energy error. Euler grows, implicit Euler decays
    (visible long before 10^5 steps: 2*10^4 and 2*10^3 steps keep the suite fast)."""
    scene = small_chain()
    n_steps = {"euler": 20_000, "implicit_euler": 2_000}.get(method, 100_000)
    # energy_blowup=inf: this test watches Euler's energy grow instead of having it stopped
    tr = mslab.simulate(scene, method, dt=1e-3, t_end=n_steps * 1e-3, save_every=n_steps // 1000,
                        energy_blowup=np.inf)
    assert tr.stats.steps == n_steps
    e = tr.energy.total
    err = np.abs(e - e[0])
    tenth = len(e) // 10
    first, last = err[1:tenth].max(), err[-tenth:].max()
    if mslab.get_method(method).symplectic:
        assert last < 2.0 * first  # bounded: no growth from the first tenth to the last
        assert err.max() < 0.02 * abs(e[0] - e.min()) + 0.02 * np.abs(tr.energy.kinetic).max()
    elif method == "euler":
        assert last > 10.0 * first and e[-1] > e[0]  # forward Euler pumps energy in
    else:
        assert e[-1] < e[0] and np.all(np.diff(e[::10]) <= 1e-12)  # implicit Euler only loses energy


def test_instability_stops_with_a_clear_message():
    scene = oscillator(stiffness=1e4, displacement=0.1, t_end=1.0)  # w = 100
    with pytest.raises(mslab.InstabilityError) as info:
        mslab.simulate(scene, "rk4", dt=0.05, stable_dt=0.0278)  # h w = 5 > 2.79
    err = info.value
    assert err.method == "rk4" and err.dt == 0.05 and err.step > 1
    assert err.t == pytest.approx(err.step * 0.05)
    for part in ("rk4", f"step {err.step}", "dt = 0.05", "predicted stable dt = 0.0278"):
        assert part in str(err)
    partial = err.trajectory
    assert not partial.complete and np.all(np.isfinite(partial.x))
    assert partial.t[-1] < err.t
    assert isinstance(err, FloatingPointError)


def test_fixed_point_divergence_names_method_step_dt_and_newton():
    scene = oscillator(stiffness=1e4, displacement=0.1, t_end=0.5)
    with pytest.raises(mslab.ConvergenceError) as info:
        mslab.simulate(scene, "implicit_euler_fp", dt=0.05)  # h w = 5: no contraction
    msg = str(info.value)
    assert "implicit_euler_fp" in msg and "step 1" in msg and "dt = 0.05" in msg
    assert "implicit_euler" in msg.replace("implicit_euler_fp", "")  # suggests Newton
    tr = mslab.simulate(scene, "implicit_euler", dt=0.05)  # Newton copes
    assert np.all(np.isfinite(tr.x))


def test_t_end_must_be_whole_number_of_steps():
    scene = small_chain()
    with pytest.raises(ValueError, match=r"use dt = 0.003003 \(333 steps\)"):
        mslab.simulate(scene, "euler", dt=0.003, t_end=1.0)
    with pytest.raises(ValueError, match="dt must be"):
        mslab.simulate(scene, "euler", dt=-1.0)


def test_save_every_keeps_bounded_samples_and_the_last_state():
    scene = small_chain()
    tr = mslab.simulate(scene, "rk4", dt=1e-3, t_end=0.105, save_every=10)
    assert tr.t.shape == (12,) and tr.x.shape == (12, 4, 2)
    np.testing.assert_allclose(tr.t[:-1], np.arange(11) * 0.01)
    assert tr.t[-1] == pytest.approx(0.105)
    full = mslab.simulate(scene, "rk4", dt=1e-3, t_end=0.105)
    np.testing.assert_array_equal(full.x[-1], tr.x[-1])
    np.testing.assert_array_equal(full.x[::10], tr.x[:-1])


def test_energy_ledger_components():
    scene = oscillator(stiffness=4.0, mass=2.0, displacement=0.5, t_end=1.0)
    tr = mslab.simulate(scene, "rk4", dt=1e-3)
    xe, ve = scene.exact(tr.t)
    np.testing.assert_allclose(tr.energy.kinetic, 0.5 * 2.0 * ve[:, 1, 0] ** 2, atol=1e-10)
    np.testing.assert_allclose(tr.energy.potential, 0.5 * 4.0 * (xe[:, 1, 0] - 1.0) ** 2, atol=1e-10)
    np.testing.assert_array_equal(tr.energy.dissipated, 0.0)


def test_only_declared_effects_are_evaluated(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("an effect the scene did not declare was evaluated")

    for cls in (Gravity, Damping, PenaltyCollider, Plane, Sphere):
        for name in ("force", "force_and_power", "energy", "power", "jacobians", "_contact"):
            if name in vars(cls):
                monkeypatch.setattr(cls, name, forbidden)
    b = SceneBuilder(2)
    p = b.add_particle([0, 0], pinned=True)
    q = b.add_particle([1, 0], velocity=[0, 1])
    r = b.add_particle([2, 0])
    b.add_spring(p, q, 10.0)
    b.add_spring(q, r, 10.0)
    scene = b.build()
    assert scene.effects == ["springs"]
    assert not scene.system.velocity_dependent and not scene.system.dissipative
    for method in mslab.methods():
        tr = mslab.simulate(scene, method, dt=1e-2, t_end=0.1)
        assert np.all(np.isfinite(tr.x))


def test_absent_velocity_dependence_skips_velocity_jacobian():
    scene = chain(4, dim=2)
    K, D = scene.system.jacobians(scene.state0.x, scene.state0.v)
    assert D is None and K.shape == (8, 8)
    damped = chain(4, dim=2, gamma=0.2)
    assert damped.system.jacobians(damped.state0.x, damped.state0.v)[1] is not None


def test_newton_converges_through_frictional_contacts():
    """A soft cube lands on a plane with friction: the force has a kink where each contact
    switches on. Full Newton steps cycle there; the line search makes implicit Euler converge."""
    scene = mslab.load_scene("jelly_cube")
    plane = next(e for e in scene.system.effects if e.name == "plane")
    assert plane.friction > 0
    tr = mslab.simulate(scene, "implicit_euler", dt=5e-3, t_end=0.5)
    assert tr.complete
    height = tr.x[..., 2] if scene.dim == 3 else tr.x[..., 1]
    assert height.min() < plane.offset + 0.05  # it did reach the floor
    assert tr.stats.n_force > tr.stats.n_iter + tr.stats.steps  # backtracking was needed


def test_initial_energy_scale_counts_kinetic_potential_and_gravity():
    from mslab.simulate import initial_energy_scale

    b = SceneBuilder(2)
    b.add_particle([0.0, 3.0], mass=2.0, velocity=[1.0, 0.0])
    b.add_particle([0.0, 0.0], mass=5.0, pinned=True)  # a pinned mass releases nothing
    b.add_gravity([0.0, -10.0])
    scene = b.build()
    kinetic = 0.5 * 2.0 * 1.0**2
    potential = 2.0 * 10.0 * 3.0 + 5.0 * 10.0 * 0.0  # U = -sum m g.x
    assert initial_energy_scale(scene) == pytest.approx(kinetic + potential + 2.0 * 10.0 * (1.0 + 3.0))
    # a drop onto a floor keeps its ledger: never stopped by the energy check
    b.add_plane([0.0, 1.0], 0.0, stiffness=1e4)
    tr = mslab.simulate(b.build(), "verlet", dt=1e-3, t_end=2.0)
    assert tr.complete and tr.energy.kinetic.max() > 50.0
