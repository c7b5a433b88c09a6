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


#: the cross-check's false alarms the detector still raises (issue 41, open): strict xfail, so a
#: detector that gets one right fails here until its mark is removed
OPEN = pytest.mark.xfail(strict=True, raises=mslab.InstabilityError,
                         reason="issue 41: the saturation detector judged on the scene's one energy scale")
OPEN_PROPERTY = {("symplectic_euler", "oscillator"), ("symplectic_euler", "driven"),
                 ("symplectic_euler_x", "oscillator"), ("symplectic_euler_x", "driven"), ("verlet", "driven"),
                 ("leapfrog", "driven"), ("forest_ruth", "driven"), ("velocity_verlet", "driven"),
                 ("yoshida6", "oscillator")}


def _open(cases, mark=OPEN):
    return [pytest.param(*c, marks=mark) for c in cases]


def _run(scene, method, dt, steps, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mslab.StabilityWarning)
        return mslab.simulate(scene, method, dt=dt, t_end=steps * dt, save_every=max(1, steps // 200), **kw)


@pytest.mark.parametrize(("method", "fraction"), _open([("yoshida6", 0.95), ("yoshida6", 0.98),
                                                        ("yoshida6", 0.995), ("symplectic_euler", 0.995),
                                                        ("symplectic_euler_x", 0.995)])
                         + [("symplectic_euler", 0.95)])
def test_no_false_alarm_just_below_the_limit(method, fraction):
    """Were stopped as saturated instabilities; the energy swings far from E(0) but stays bounded."""
    scene = oscillator()
    tr = _run(scene, method, fraction * st.oscillator_limit(method), 20000)
    assert tr.complete
    total = tr.energy.total  # bounded: the second half reaches no more than the first
    assert np.max(total[100:]) <= 1.01 * np.max(total[:101])


@pytest.mark.parametrize("method", _open([("euler",), ("symplectic_euler_x",)]))
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


@pytest.mark.parametrize(("method", "scene"), [
    pytest.param(m, s, marks=OPEN) if (m, s) in OPEN_PROPERTY else (m, s)
    for m in mslab.methods() if mslab.get_method(m).explicit for s in ("oscillator", "free_fall", "driven")])
def test_no_false_alarm_below_the_limit_any_method(method, scene):
    """Every explicit method with a stable dt, at 0.95-0.995 of it: the run completes."""
    sc = {"oscillator": oscillator, "free_fall": free_fall, "driven": driven}[scene]()
    m = mslab.get_method(method)
    limit = predicted_stable_dt(sc, m) if scene != "free_fall" else 0.01
    if not limit or not np.isfinite(limit):
        pytest.skip(f"{method} has no stable dt on {scene}")
    for fraction in (0.95, 0.98, 0.995):
        assert _run(sc, m, fraction * limit, 4000).complete


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
