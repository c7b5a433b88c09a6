"""The outside review of issues 37 and 39 (defects D1-D16): each planted case, refused or held."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import mslab

pytestmark = pytest.mark.filterwarnings("ignore::mslab.StabilityWarning")


def chain() -> mslab.Scene:
    return mslab.load_scene("chain")


def with_state(scene: mslab.Scene, **arrays) -> mslab.Scene:
    return dataclasses.replace(scene, state0=dataclasses.replace(scene.state0, **arrays))


# -- D3: a pinned particle given a velocity ------------------------------------------------------
@pytest.mark.parametrize("method", ["rk4", "symplectic_euler", "verlet", "implicit_euler"])
def test_a_pinned_particle_with_a_velocity_is_refused_naming_it(method):
    sc = chain()
    pinned = int(np.flatnonzero(sc.system.inv_mass == 0)[0])
    v = np.zeros_like(sc.state0.v)
    v[pinned] = [1.0, 0.0]
    bad = with_state(sc, v=v)
    with pytest.raises(ValueError, match=rf"state0\.v: pinned particle {pinned} .*velocity") as info:
        mslab.simulate(bad, method, 1e-3, 0.05)
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match=r"state0\.v: pinned particle"):
        mslab.Simulation(bad, method, 1e-3)
    free = int(np.flatnonzero(sc.system.inv_mass != 0)[0])  # a free particle's velocity is fine
    v = np.zeros_like(sc.state0.v)
    v[free] = [1.0, 0.0]
    assert mslab.simulate(with_state(sc, v=v), method, 1e-3, 0.01).complete


# -- D7: a replaced state0 that is no state of this scene ----------------------------------------
@pytest.mark.parametrize(("make", "error", "text"), [
    (lambda x: x.tolist(), TypeError, r"state0\.x .*numpy array of floats, got list"),
    (lambda x: x[:5], ValueError, r"state0\.x .*shape \(10, 2\).*got \(5, 2\)"),
    (lambda x: np.array(1.0), ValueError, r"state0\.x .*got \(\)"),
    (lambda x: x.ravel(), ValueError, r"state0\.x .*got \(20,\)"),
    (lambda x: x.astype(int), TypeError, r"state0\.x .*floats, got an array of int"),
])
@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_state0_of_the_wrong_kind_is_one_error_naming_it(make, error, text, backend):
    sc = chain()
    assert sc.n_particles == 10 and sc.dim == 2
    with pytest.raises(error, match=text):
        mslab.simulate(with_state(sc, x=make(sc.state0.x)), backend=backend)


# -- D1: the session's own system, method, counters and length cannot change the run -------------
BACKENDS = ["numpy", "numba"]


@pytest.mark.parametrize("backend", BACKENDS)
def test_what_a_session_hands_out_cannot_change_its_run(backend):
    clean = mslab.simulate(chain(), "rk4", 1e-3, 0.1, backend=backend)
    sim = mslab.Simulation(chain(), "rk4", 1e-3, t_end=0.1, backend=backend)
    sim.advance(50)
    springs = sim.system.effects[0]
    with pytest.raises(ValueError, match="read-only"):
        springs.stiffness[:] *= 100
    with pytest.raises(ValueError, match="read-only"):
        sim.system.mass[:] = 5.0
    with pytest.raises(ValueError, match="read-only"):
        sim.integrator.b[:] = [1.0, 0.0, 0.0, 0.0]
    for name in ("end", "system", "integrator", "stats", "dt", "save_every"):
        with pytest.raises(AttributeError):
            setattr(sim, name, 10**6)
    stats = sim.stats
    stats.n_force = 10**9  # a copy
    sim.advance()
    assert sim.step == 100 and sim.stats.n_force == clean.stats.n_force
    out = sim.trajectory
    np.testing.assert_array_equal(out.x, clean.x)
    assert out.stats.n_force == clean.stats.n_force


# -- D2: a finished session's trajectory: one reader's edits never reach the next -----------------
@pytest.mark.parametrize("t_end", [0.1, None])
def test_a_finished_sessions_trajectory_is_not_shared_writable(t_end):
    sim = mslab.Simulation(chain(), "rk4", 1e-3, t_end=t_end)
    sim.advance(100)
    first = sim.trajectory
    for array in (first.x, first.v, first.energy.kinetic, first.energy.potential):
        try:
            array[...] = 7.0
        except ValueError as err:  # a read-only view of the finished run's store
            assert "read-only" in str(err)
    again = sim.trajectory
    assert not np.any(again.x == 7.0) and not np.any(again.energy.kinetic == 7.0)
    # simulate drops its session: its result is the caller's own, writable, as before
    result = mslab.simulate(chain(), "rk4", 1e-3, 0.1)
    result.x[:] = 0.0
    assert result.x.flags.writeable
