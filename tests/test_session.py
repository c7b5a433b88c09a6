"""Simulation, the stepping session: any chunking is bitwise the same run as one simulate() call."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

import mslab
from mslab import fast
from mslab.scenes import generators

pytestmark = pytest.mark.filterwarnings("ignore::mslab.StabilityWarning")

#: uneven chunks, repeated: a step, a prime, another prime, ...
CHUNKS = (1, 7, 13, 4, 11)
N_STEPS = 60
SAVE_EVERY = 4


def scene():
    """A damped 2D chain under gravity (velocity-dependent forces: every family's extra stages)."""
    return generators.chain(5, dim=2, stiffness=300.0, damping=0.3, gamma=0.2)


def backends(method: str) -> list[str]:
    """Both backends where the compiled path applies to the method (the registry decides)."""
    reason = fast.unsupported(scene().system, mslab.get_method(method))
    return ["numpy"] if reason else ["numpy", "numba"]


CASES = [(m, b) for m in mslab.methods() for b in backends(m)]


def chunked(sim: mslab.Simulation, total: int) -> None:
    for n in itertools.cycle(CHUNKS):
        n = min(n, total - sim.step)
        if n == 0:
            return
        sim.advance(n)


def assert_bitwise(a: mslab.Trajectory, b: mslab.Trajectory) -> None:
    for name in ("t", "x", "v"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in ("kinetic", "potential", "dissipated", "external"):
        np.testing.assert_array_equal(getattr(a.energy, name), getattr(b.energy, name), err_msg=name)
    sa, sb = a.stats.as_dict(), b.stats.as_dict()
    sa.pop("wall_time"), sb.pop("wall_time")
    assert sa == sb


@pytest.mark.parametrize(("method", "backend"), CASES, ids=[f"{m}-{b}" for m, b in CASES])
def test_uneven_chunks_are_bitwise_one_long_run(method, backend):
    dt = 2e-3
    whole = mslab.simulate(scene(), method, dt=dt, t_end=N_STEPS * dt, save_every=SAVE_EVERY, backend=backend)
    # an open-ended session (no t_end) and one of declared length, both in uneven chunks
    for t_end in (None, N_STEPS * dt):
        sim = mslab.Simulation(scene(), method, dt=dt, t_end=t_end, save_every=SAVE_EVERY, backend=backend)
        chunked(sim, N_STEPS)
        assert sim.step == N_STEPS and sim.t == N_STEPS * dt
        assert sim.compiled == (backend == "numba")
        assert_bitwise(sim.trajectory, whole)
        state = sim.state
        np.testing.assert_array_equal(state.x, whole.x[-1])
        np.testing.assert_array_equal(state.v, whole.v[-1])
        assert state.dissipated == whole.energy.dissipated[-1]
        assert sim.stats.n_force == whole.stats.n_force and sim.stats.steps == N_STEPS


@pytest.mark.parametrize("method", ["verlet", "leapfrog", "velocity_verlet"])
def test_two_step_methods_keep_their_memory_across_calls(method):
    """The route the issue found broken: a new simulate() per chunk restarts Verlet's start-up step.

    A session continues instead; restarting (what users had to do) is measurably another run.
    """
    dt, n = 2e-3, 40
    whole = mslab.simulate(scene(), method, dt=dt, t_end=n * dt)
    # the same declared length, so the same backend (an open-ended session may compile where 40
    # steps alone take numpy: equal then only to round-off, which is not what this test is about)
    sim = mslab.Simulation(scene(), method, dt=dt, t_end=n * dt)
    for _ in range(n // 10):
        sim.advance(10)
    np.testing.assert_array_equal(sim.state.x, whole.x[-1])
    restarted = scene()
    for _ in range(n // 10):
        tr = mslab.simulate(restarted, method, dt=dt, t_end=10 * dt)
        restarted = dataclasses.replace(restarted, state0=mslab.State(tr.x[-1], tr.v[-1]))
    if method == "verlet":  # the start-up step and velocity estimate of every restart
        assert not np.array_equal(restarted.state0.x, whole.x[-1])


def test_advance_by_time_and_to_the_end():
    sim = mslab.Simulation(scene(), "rk4", dt=1e-3, t_end=0.05, save_every=10)
    sim.advance(t=0.016)
    assert sim.step == 16
    sim.advance()
    assert sim.step == 50 and sim.trajectory.t[-1] == pytest.approx(0.05)
    with pytest.raises(ValueError, match="ends at step 50"):
        sim.advance(1)
    with pytest.raises(ValueError, match="whole number of steps"):
        mslab.Simulation(scene(), "rk4", dt=1e-3).advance(t=0.0165)
    # a finite t_end too far for float64 steps (t_end / dt infinite, or beyond 2**53): a ValueError
    # naming it, never an OverflowError from round() (found by tests/test_contract_property.py)
    for t_end in (1.797693134862316e306, 2.0**53 * 1e-3 * 4):
        with pytest.raises(ValueError, match="more than a run can count"):
            mslab.Simulation(scene(), "rk4", dt=1e-3, t_end=t_end)
        with pytest.raises(ValueError, match="more than a run can count"):
            mslab.Simulation(scene(), "rk4", dt=1e-3).advance(t=t_end)


def test_open_session_saves_on_the_grid_and_shows_the_current_state():
    sim = mslab.Simulation(scene(), "rk4", dt=1e-3, save_every=10)
    sim.advance(25)
    tr = sim.trajectory
    np.testing.assert_array_equal(np.round(tr.t / 1e-3), [0, 10, 20, 25])
    sim.advance(5)
    np.testing.assert_array_equal(np.round(sim.trajectory.t / 1e-3), [0, 10, 20, 30])
    assert tr.x.shape[0] == 4  # a trajectory already handed out does not change


def test_blowup_in_a_session_is_the_error_of_one_long_run():
    stiff = generators.chain(6, dim=2, stiffness=1e4)
    with pytest.raises(mslab.InstabilityError) as whole:
        mslab.simulate(stiff, "rk4", dt=0.02, t_end=20.0, save_every=3, backend="numpy")
    sim = mslab.Simulation(stiff, "rk4", dt=0.02, save_every=3, backend="numpy")
    with pytest.raises(mslab.InstabilityError) as chunks:
        chunked(sim, 1000)
    a, b = chunks.value, whole.value
    assert (a.step, a.t, str(a)) == (b.step, b.t, str(b))
    assert_bitwise(a.trajectory, b.trajectory)
    with pytest.raises(ValueError, match="stopped at step"):
        sim.advance(1)


def test_auto_backend_is_decided_once_from_the_expected_work():
    """Open-ended: HORIZON steps (fixed at the start); declared: the length."""
    from mslab.simulation import HORIZON

    method = mslab.get_method("symplectic_euler")
    small, cloth = generators.chain(5, dim=2), generators.cloth(64, 64, gravity=9.81)
    for sc in (small, cloth):
        sim = mslab.Simulation(sc, method, dt=1e-4, backend="auto", check_stability=False)
        sim.advance(1)
        assert sim.compiled == fast.worth_compiling(sc.system, method, HORIZON)
    assert mslab.Simulation(cloth, method, dt=1e-4, backend="auto", check_stability=False).compiled
    assert mslab.Simulation(small, method, dt=1e-4, backend="auto").compiled  # 3000 steps: ~0.3 s numpy
    declared = mslab.Simulation(small, method, dt=1e-4, t_end=0.01, backend="auto")  # 100 steps
    assert not declared.compiled and not fast.worth_compiling(small.system, method, 100)


# -- the saturation detector (issue 23 item 7): growth with bounded positions ends the run ------------

def stiff_pairs():
    """A 1D chain of unit masses, springs k = 1, 1e6, 1, 1e6; the first stiff spring starts stretched."""
    b = mslab.SceneBuilder(1)
    ps = [b.add_particle([float(i)], mass=1.0, pinned=i == 0) for i in range(5)]
    for (p, q), k in zip(itertools.pairwise(ps), (1.0, 1e6, 1.0, 1e6), strict=True):
        b.add_spring(p, q, k)
    sc = b.build()
    x = sc.state0.x.copy()
    x[2, 0] += 0.1
    return dataclasses.replace(sc, state0=mslab.State(x, sc.state0.v))


def resting_contact():
    """A particle resting on a penalty floor (k = 1e4, m = 1) under gravity, nudged at 1 mm/s."""
    b = mslab.SceneBuilder(2)
    b.add_particle([0.0, -9.81 / 1e4], mass=1.0, velocity=[0.0, 1e-3])
    b.add_gravity([0.0, -9.81])
    b.add_plane([0.0, 1.0], 0.0, stiffness=1e4)
    return b.build()


@pytest.mark.parametrize(("make", "method", "steps"), [(stiff_pairs, "rk4", 20000),
                                                       (resting_contact, "verlet", 5000)])
def test_saturating_instability_ends_in_instability_error(make, method, steps):
    """Just beyond the predicted limit the unstable mode grows, then saturates with bounded positions
    (the stiff springs swing through zero length; the particle bounces). At 0.98 x the limit nothing
    grows; at 1.02 x the old fixed 1e4 x threshold never fired, the growth check does."""
    from mslab.ledger import initial_energy_scale
    from mslab.stability import predicted_stable_dt

    sc = make()
    limit = predicted_stable_dt(sc, mslab.get_method(method))
    below = mslab.simulate(sc, method, dt=0.98 * limit, t_end=steps * 0.98 * limit, save_every=50)
    assert below.complete
    dt = 1.02 * limit
    unchecked = mslab.simulate(sc, method, dt=dt, t_end=steps * dt, save_every=50, energy_blowup=np.inf)
    gain = (unchecked.energy.total - unchecked.energy.total[0]) / initial_energy_scale(sc)
    assert 10 < gain.max() < 1e4  # grew, but under the old threshold: the old check let it through
    # positions stay finite, 100 x under the position blow-up (1e6 x the size): that check never fires
    assert np.abs(unchecked.x).max() < 1e4 * (1 + np.abs(sc.state0.x).max())
    with pytest.raises(mslab.InstabilityError, match="energy ledger") as info:
        mslab.simulate(sc, method, dt=dt, t_end=steps * dt, save_every=50)
    err = info.value
    assert "saturated" in str(err) and err.step < steps
    assert not err.trajectory.complete and err.trajectory.t[-1] < err.t


@pytest.mark.parametrize("field", ["x", "v"])
def test_a_non_finite_initial_state_is_refused_before_any_work(field):
    """A scene built around the SceneBuilder with NaN in its state: one clear error, no step taken."""
    scene = mslab.load_scene("chain")
    values = getattr(scene.state0, field).copy()
    values[3, 1] = np.nan
    state = dataclasses.replace(scene.state0, **{field: values})
    bad = dataclasses.replace(scene, state0=state)
    what = "positions" if field == "x" else "velocities"
    with pytest.raises(ValueError, match=rf"initial state: {what} are not finite .* particles \[3\]"):
        mslab.Simulation(bad, "rk4", 1e-3)
    with pytest.raises(ValueError, match="initial state"):
        mslab.simulate(bad, "rk4", 1e-3, t_end=0.01)


def test_springs_take_one_value_for_all_or_one_per_spring():
    """A single stiffness is every spring's, on both backends alike; a wrong count is one clear error."""
    from mslab import fast
    from mslab.effects import Springs

    pairs = np.array([[0, 1], [1, 2]])
    x = np.array([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0], [2.3, 0.0, 0.0]])
    one = Springs(pairs, 500.0, 1.0, 0.0, 3)
    each = Springs(pairs, [500.0, 500.0], [1.0, 1.0], [0.0, 0.0], 3)
    for springs in (one, each):
        system = mslab.System(np.ones(3), np.zeros(3, dtype=bool), [springs], 3)
        f_numpy = system.force(x, np.zeros_like(x))
        assert np.allclose(f_numpy[:, 0], [500 * 0.1, 500 * 0.2 - 500 * 0.1, -500 * 0.2])
        f_compiled = fast.ForceModel(system).force(x, np.zeros_like(x))[0]
        assert np.max(np.abs(f_compiled - f_numpy)) <= 8 * np.finfo(float).eps * 500 * 2.3  # k |d|
    with pytest.raises(ValueError, match=r"stiffness needs one value or one per spring \(2\)"):
        Springs(pairs, [1.0, 2.0, 3.0], 1.0, 0.0, 3)


# -- issue 39: one definition of what a run saves and counts, also where it stops early -----------------

BLOWUPS = [("topology_pair", "euler", "numpy"), ("topology_pair", "euler", "numba"),
           ("topology_pair", "midpoint", "numpy"), ("stiff_chain", "midpoint", "numpy"),
           ("stiff_chain", "euler", "numba")]


@pytest.mark.parametrize(("name", "method", "backend"), BLOWUPS, ids=["-".join(c) for c in BLOWUPS])
def test_a_blowup_saves_and_counts_the_same_in_any_chunks(name, method, backend):
    """A ledger bound met at a saved sample before a position blow-up stops every chunking there."""
    sc = mslab.load_scene(name)
    dt = sc.settings.dt * 4
    options = {"dt": dt, "t_end": 4000 * dt, "save_every": 7, "backend": backend}
    with pytest.raises(mslab.InstabilityError) as whole:
        mslab.simulate(sc, method, **options)
    for chunks in ((1, 7, 13, 4, 11), (3,), (50, 1)):
        sim = mslab.Simulation(sc, method, **options)
        with pytest.raises(mslab.InstabilityError) as parts:
            for n in itertools.cycle(chunks):
                sim.advance(min(n, 4000 - sim.step))
        a, b = parts.value, whole.value
        assert (a.step, str(a)) == (b.step, str(b))
        assert_bitwise(a.trajectory, b.trajectory)


@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_fast_mass_spring_counts_its_factorisation_in_any_chunks(backend):
    """The global matrix is factored once per run, counted in a session as in one call (was 0 vs 1)."""
    options = {"dt": 2e-3, "t_end": N_STEPS * 2e-3, "save_every": SAVE_EVERY, "backend": backend}
    sc = scene()
    first = mslab.simulate(sc, "fast_mass_spring", **options)
    sim = mslab.Simulation(sc, "fast_mass_spring", **options)
    chunked(sim, N_STEPS)
    again = mslab.simulate(sc, "fast_mass_spring", **options)
    assert first.stats.n_factor == sim.stats.n_factor == again.stats.n_factor == 1
    assert_bitwise(sim.trajectory, first)
