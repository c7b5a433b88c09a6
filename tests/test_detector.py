"""The instability detector (issue 41): no false alarm on bounded or drifting energy, no miss where a
group of particles grows geometrically while a heavy fast body elsewhere sets the scene's energy scale."""

import dataclasses
import itertools
import warnings

import numpy as np
import pytest

import mslab
from mslab import stability as st
from mslab.ledger import initial_energy_scale
from mslab.scenes.oscillator import oscillator
from mslab.stability import predicted_stable_dt


def _bystander(b: mslab.SceneBuilder, dim: int) -> None:
    """A heavy body far up, flying fast, joined to nothing: the scene's energy scale is its."""
    position = np.zeros(dim)
    position[-1] = 1e5
    velocity = np.zeros(dim)
    velocity[0] = 300.0
    b.add_particle(position, mass=1e3, velocity=velocity)


def resting_contact_with_bystander(bystander=True):
    b = mslab.SceneBuilder(2)
    b.add_particle([0.0, -9.81 / 1e4], mass=1.0, velocity=[0.0, 1e-3])
    if bystander:
        _bystander(b, 2)
    b.add_gravity([0.0, -9.81])
    b.add_plane([0.0, 1.0], 0.0, stiffness=1e4)
    return b.build()


def stiff_pairs_with_bystander(bystander=True):
    b = mslab.SceneBuilder(1)
    ps = [b.add_particle([float(i)], mass=1.0, pinned=i == 0) for i in range(5)]
    for (p, q), k in zip(itertools.pairwise(ps), (1.0, 1e6, 1.0, 1e6), strict=True):
        b.add_spring(p, q, k)
    if bystander:
        _bystander(b, 1)
    sc = b.build()
    x = sc.state0.x.copy()
    x[2, 0] += 0.1
    return dataclasses.replace(sc, state0=mslab.State(x, sc.state0.v))


def free_fall():
    b = mslab.SceneBuilder(2)
    b.add_particle([0.0, 0.0], mass=1.0)
    b.add_gravity(9.81)
    return b.build()


def driven():
    """A damped spring pendulum in a wind: driven, dissipating, no fixed energy."""
    b = mslab.SceneBuilder(2)
    anchor = b.add_particle([0.0, 0.0], pinned=True)
    bob = b.add_particle([1.0, 0.0], mass=1.0)
    b.add_spring(anchor, bob, 100.0, damping=0.1)
    b.add_gravity(9.81)
    b.add_wind([3.0, 0.0], drag=0.2)
    return b.build()


def _run(scene, method, dt, steps, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mslab.StabilityWarning)
        return mslab.simulate(scene, method, dt=dt, t_end=steps * dt, save_every=max(1, steps // 200), **kw)


@pytest.mark.parametrize(("method", "fraction"), [("yoshida6", 0.95), ("yoshida6", 0.98), ("yoshida6", 0.995),
                                                 ("symplectic_euler", 0.995), ("symplectic_euler_x", 0.995),
                                                 ("symplectic_euler", 0.95)])
def test_no_false_alarm_just_below_the_limit(method, fraction):
    """Were stopped as saturated instabilities; the energy swings far from E(0) but stays bounded."""
    scene = oscillator()
    tr = _run(scene, method, fraction * st.oscillator_limit(method), 20000)
    assert tr.complete
    total = tr.energy.total  # bounded: the second half reaches no more than the first
    assert np.max(total[100:]) <= 1.01 * np.max(total[:101])


@pytest.mark.parametrize("method", ["euler", "symplectic_euler_x"])
def test_no_false_alarm_on_a_linear_drift(method):
    """Free fall: the energy drifts linearly (the method's known first-order error), read as a rise."""
    dt = 0.01
    tr = _run(free_fall(), method, dt, 20000)
    assert tr.complete
    drift = tr.energy.total - tr.energy.total[0]
    n = np.arange(drift.size) * 100
    assert drift[-1] == pytest.approx(9.81**2 * dt * n[-1] * dt / 2, rel=1e-3)  # |D E| = m g^2 h t / 2


@pytest.mark.parametrize(("make", "method", "steps"), [(resting_contact_with_bystander, "verlet", 5000),
                                                       (stiff_pairs_with_bystander, "rk4", 20000)])
def test_no_miss_behind_a_heavy_fast_body(make, method, steps):
    sc = make()
    limit = predicted_stable_dt(sc, mslab.get_method(method))
    assert _run(sc, method, 0.98 * limit, steps).complete
    dt = 1.02 * limit
    unchecked = _run(sc, method, dt, steps, energy_blowup=np.inf)
    assert unchecked.complete  # the old checks let it through: bounded positions, a small global gain
    alone = make(bystander=False)  # the same particles without the bystander: their own energy scale
    kinetic = 0.5 * np.sum(alone.system.mass[None, :, None] * unchecked.v[:, :-1] ** 2, axis=(1, 2))
    assert kinetic.max() > 10.0 * initial_energy_scale(alone)  # it did blow up
    global_gain = (unchecked.energy.total - unchecked.energy.total[0]) / initial_energy_scale(sc)
    assert global_gain.max() < 1.0  # under the scene's energy scale: no global check can see it
    with pytest.raises(mslab.InstabilityError, match="energy ledger") as info:
        _run(sc, method, dt, steps)
    assert "particles [0" in str(info.value) and info.value.step < steps  # the group, not the bystander


def pendulum_in_wind():
    """The spring pendulum (k = 1000, released from the horizontal) under gravity, in a 3 m/s wind."""
    b = mslab.SceneBuilder(2)
    anchor = b.add_particle([0.0, 0.0], pinned=True)
    bob = b.add_particle([1.0, 0.0], mass=1.0)
    b.add_spring(anchor, bob, 1000.0)
    b.add_gravity(9.81)
    b.add_wind([3.0, 0.0], drag=0.2)
    return b.build()


def test_no_miss_on_a_slow_growth_under_the_fixed_bound():
    """Forward Euler at 5 x its limit: the swing's energy grows geometrically for 29000 steps and ends
    thousands of times the scale, under the fixed 1e4 bound, with positions far under theirs. Was
    finished silently (nothing saturated); the growth of the predicted unstable mode stops it."""
    sc, dt, steps = pendulum_in_wind(), 1e-3, 29000
    limit = predicted_stable_dt(sc, mslab.get_method("euler"))
    assert dt > 4 * limit
    unchecked = _run(sc, "euler", dt, steps, energy_blowup=np.inf)
    gain = (unchecked.energy.total - unchecked.energy.total[0]) / initial_energy_scale(sc)
    assert unchecked.complete and 1e3 < gain.max() < 1e4 and np.abs(unchecked.x).max() < 100
    half = unchecked.t.size // 2  # geometric: the last quarter of the run multiplies the gain 50-fold
    assert gain[-1] > 50 * gain[half + half // 2] > 0
    with pytest.raises(mslab.InstabilityError, match="energy ledger .* unstable at this dt") as info:
        _run(sc, "euler", dt, steps)
    assert info.value.step < steps


def test_a_slow_growth_stops_alike_on_both_backends_and_in_any_chunks():
    """The stop of the slow growth above (a rise read at the checks, the stable dt predicted at its
    first qualifying check) is the same step and message on numpy and numba and in chunks."""
    sc, dt, steps = pendulum_in_wind(), 1e-3, 29000
    stops = []
    for backend in ("numpy", "numba"):
        with pytest.raises(mslab.InstabilityError) as info:
            _run(sc, "euler", dt, steps, backend=backend)
        stops.append(info.value)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mslab.StabilityWarning)
        sim = mslab.Simulation(sc, "euler", dt=dt, t_end=steps * dt, save_every=steps // 200, backend="numba")
    with pytest.raises(mslab.InstabilityError) as info:
        for n in itertools.cycle((997, 1503, 3001)):
            sim.advance(min(n, steps - sim.step))
    stops.append(info.value)
    assert len({(e.step, str(e)) for e in stops}) == 1
    np.testing.assert_array_equal(stops[2].trajectory.x, stops[1].trajectory.x)


EXPLICIT = [m for m in mslab.methods() if mslab.get_method(m).explicit]


@pytest.mark.parametrize("method", EXPLICIT)
def test_no_false_alarm_below_the_limit_and_a_stop_above_it(method):
    """Every explicit method: at 0.95-0.995 of its stable dt the oscillator (swinging through zero
    length at large amplitude, linear at small) and a driven scene complete, free fall too; at 1.02
    and 1.1 x the limit on the linear oscillator every run whose step matrix has an eigenvalue
    outside the unit circle stops (yoshida6 is stable again at 1.1 x, beyond a gap in its interval:
    beyond the predicted stable dt it may stop all the same, the prediction being the first edge).
    Compiled loops: 4000 steps a run in well under a second."""
    m = mslab.get_method(method)
    assert _run(free_fall(), m, 0.01, 4000, backend="numba").complete
    for make in (oscillator, lambda: oscillator(displacement=1e-3), driven):
        sc = make()
        limit = predicted_stable_dt(sc, m)
        for fraction in (0.95, 0.98, 0.995) if limit else ():  # forward Euler, heun, rk6: no stable dt
            assert _run(sc, m, fraction * limit, 4000, backend="numba").complete
    limit = st.oscillator_limit(method)
    for fraction in (1.02, 1.05, 1.1) if limit else ():
        radius = float(st.spectral_radius(st.amplification_matrix(method, fraction * limit)))
        if radius > 1:
            with pytest.raises(mslab.InstabilityError):
                _run(oscillator(displacement=1e-3), m, fraction * limit, 4000, backend="numba")


def test_energy_groups_are_the_connected_components():
    """The groups judged apart are scipy's connected components of the springs' pairs."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from mslab.ledger import MAX_GROUPS, energy_groups

    rng = np.random.default_rng(3)
    for _ in range(30):
        n = int(rng.integers(2, 30))
        pairs = {tuple(sorted(p)) for p in rng.integers(0, n, (int(rng.integers(0, 25)), 2)) if p[0] != p[1]}
        b = mslab.SceneBuilder(2)
        for k in range(n):
            b.add_particle([float(k), float(k % 3)])
        for p, q in sorted(pairs):
            b.add_spring(int(p), int(q), 10.0)
        b.add_gravity(9.81)
        b.add_plane([0.0, 1.0], -1.0, stiffness=100.0)
        groups = energy_groups(b.build())
        i, j = (np.array([p[k] for p in pairs], dtype=int) for k in (0, 1))
        graph = csr_matrix((np.ones(i.size), (i, j)), shape=(n, n))
        count, labels = connected_components(graph, directed=False)
        if count == 1:
            assert groups is None
            continue
        for k in range(count):  # a component lies in one group; with few components, alone in it
            assert len(set(groups[labels == k])) == 1
        if count <= MAX_GROUPS:
            assert len(set(groups)) == count


def drop(height, k=1e5, mass=1.0):
    """Lesson 08's drop: one particle at ``height`` above a penalty floor y >= 0, under gravity."""
    b = mslab.SceneBuilder(2)
    b.add_particle([0.0, height], mass=mass)
    b.add_gravity([0.0, -9.81])
    b.add_plane([0.0, 1.0], 0.0, stiffness=k)
    return b.build()


def _drop_run(method, fraction, height, **kw):
    """One second of the drop at ``fraction`` of the predicted stable dt (a whole number of steps)."""
    sc = drop(height)
    n = int(round(1.0 / (fraction * predicted_stable_dt(sc, mslab.get_method(method)))))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mslab.StabilityWarning)
        return mslab.simulate(sc, method, dt=1.0 / n, t_end=1.0, **kw)


def test_the_contact_catapult_just_beyond_its_limit_is_stopped():
    """Lesson 08's miss: at 1.1 x the contact's limit symplectic Euler throws the particle dropped from
    0.1 m to 1.26 m (energy x 12, where the exact motion rises back to 0.1 m) within one contact of a
    step or two; the ledger check's rise rules never fired and the run completed. The impact rule
    (a jump out of calm, kept) stops it after the first contact."""
    unchecked = _drop_run("symplectic_euler", 1.1, 0.1, energy_blowup=np.inf)
    assert unchecked.complete and unchecked.x[:, 0, 1].max() > 1.0 and np.all(np.isfinite(unchecked.x))
    with pytest.raises(mslab.InstabilityError, match="an impact .* unstable at this dt") as info:
        _drop_run("symplectic_euler", 1.1, 0.1)
    assert np.sqrt(2 * 0.1 / 9.81) < info.value.t < 0.5  # after the first contact, long before the end


@pytest.mark.parametrize("method", ["symplectic_euler", "verlet", "rk4"])
def test_every_catapult_above_a_metre_beyond_the_limit_is_stopped(method):
    """Eleven start heights 0.100-0.120 m at 1.1 x the limit: every run that throws the particle above
    1 m (ten times its start, unchecked) is stopped (by the impact rule, or by the rise rule where the
    jump exceeds the whole energy scale)."""
    thrown = 0
    for height in np.linspace(0.1, 0.12, 11):
        unchecked = _drop_run(method, 1.1, height, energy_blowup=np.inf)
        if unchecked.x[:, 0, 1].max() > 1.0:
            thrown += 1
            with pytest.raises(mslab.InstabilityError, match="energy ledger .* unstable at this dt"):
                _drop_run(method, 1.1, height)
    assert thrown >= 2


@pytest.mark.parametrize("method", EXPLICIT)
def test_no_false_alarm_on_a_contact_below_its_limit(method):
    """Every explicit method with a stable dt: the drop at 0.9-0.99 x the contact's limit from four
    heights completes (the contact may gain energy there, up to x 9 for symplectic Euler at 0.99 x:
    the method's error near its limit, not an instability)."""
    if not predicted_stable_dt(drop(0.1), mslab.get_method(method)):
        return  # forward Euler, heun, midpoint, rk6: no stable dt on an undamped contact
    for fraction, height in itertools.product((0.9, 0.95, 0.99), (0.1, 0.107, 0.113, 0.12)):
        assert _drop_run(method, fraction, height, backend="numba").complete


def stretched_cross(velocity):
    """A unit mass held by four springs (k = 100, rest length 1) to anchors 2 m away on the axes, thrown.

    At the start the springs pull with tension k (2 - 1): sideways stiffness k / 2 each. Thrown far,
    a spring stretched to length L stiffens sideways to k (1 - 1 / L): the states the run reaches are
    stiffer than its start, whose linearisation sets the predicted stable dt."""
    b = mslab.SceneBuilder(2)
    centre = b.add_particle([0.0, 0.0], mass=1.0, velocity=velocity)
    for anchor in ([2.0, 0.0], [-2.0, 0.0], [0.0, 2.0], [0.0, -2.0]):
        b.add_spring(centre, b.add_particle(anchor, pinned=True), 100.0, rest_length=1.0)
    return b.build()


def test_a_run_within_the_start_limit_but_beyond_that_of_the_states_it_reaches_is_stopped():
    """yoshida6 at 0.9 x the stable dt predicted at the start: the thrown particle reaches stretched states
    whose linearisation puts dt beyond their limit (1.04-1.14 x); its energy grew a thousand-fold and it
    flew 35 times farther than the anchors, under the position bound. The ledger gave no verdict within
    the start's limit and the run completed; linearised again at the state of the rise, it stops."""
    sc = stretched_cross([30.0, 5.0])
    dt = 0.9 * predicted_stable_dt(sc, mslab.get_method("yoshida6"))
    unchecked = _run(sc, "yoshida6", dt, 20000, energy_blowup=np.inf, check_stability=False)
    gain = (unchecked.energy.total - unchecked.energy.total[0]) / initial_energy_scale(sc)
    assert unchecked.complete and gain.max() > 100 and np.abs(unchecked.x).max() > 20
    reached = [dataclasses.replace(sc, state0=mslab.State(unchecked.x[i], unchecked.v[i]))
               for i in (50, 100, 150)]
    assert max(dt / st.max_stable_dt(s, "yoshida6") for s in reached) > 1.02
    with pytest.raises(mslab.InstabilityError, match="in the state the run reached") as info:
        _run(sc, "yoshida6", dt, 20000)
    assert info.value.step < 20000


def test_a_thrown_run_within_the_limit_of_every_state_it_reaches_completes():
    """Symplectic Euler at 0.9 x on the cross thrown more gently: its energy swings 2-fold (the method's error
    near the limit) and every state it reaches is within its own limit: linearised again, still no verdict."""
    sc = stretched_cross([10.0, 2.0])
    dt = 0.9 * predicted_stable_dt(sc, mslab.get_method("symplectic_euler"))
    tr = _run(sc, "symplectic_euler", dt, 20000)
    assert tr.complete
    states = [dataclasses.replace(sc, state0=mslab.State(tr.x[i], tr.v[i])) for i in range(0, tr.t.size, 10)]
    assert max(dt / st.max_stable_dt(s, "symplectic_euler") for s in states) < 1.0
