"""The compiled fast path (mslab.fast) equals the numpy reference: forces, trajectories, counters."""

from __future__ import annotations

import numpy as np
import pytest

import mslab
from mslab import fast
from mslab.effects import Springs
from mslab.scenes import generators

pytestmark = [
    pytest.mark.skipif(not fast.available(), reason="numba does not import"),
    # some runs below use methods outside their stability region on purpose (equality, blow-up)
    pytest.mark.filterwarnings("ignore::mslab.StabilityWarning"),
]

#: every registered method with a compiled loop (the registry decides, not this list)
FAST_METHODS = [m for m in mslab.methods() if mslab.get_method(m).compiled is not None]


def close(a, b, tol=1e-12):
    """|a - b| <= tol relative to the size of the numbers (at least 1)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(1.0, float(np.max(np.abs(b))) if b.size else 1.0)
    return a.shape == b.shape and float(np.max(np.abs(a - b), initial=0.0)) <= tol * scale


def random_springs(rng, n=12, m=30, dim=3, damped=True):
    i = rng.integers(0, n, m)
    j = (i + rng.integers(1, n, m)) % n
    return Springs(np.stack([i, j], 1), rng.uniform(1, 100, m), rng.uniform(0.1, 2, m),
                   rng.uniform(0, 3, m) if damped else np.zeros(m), n)


@pytest.mark.parametrize("damped", [False, True])
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_spring_kernel_equals_numpy(dim, damped):
    rng = np.random.default_rng(dim + 10 * damped)
    springs = random_springs(rng, dim=dim, damped=damped)
    x, v = rng.normal(size=(12, dim)), rng.normal(size=(12, dim))
    x[3] = x[springs.j[0]] if springs.i[0] == 3 else x[3]
    x[springs.i[1]] = x[springs.j[1]]  # a spring of zero length: no force, no NaN
    with fast.use_backend("numpy"):
        f_ref, p_ref = springs.force_and_power(x, v)
        f_ref_only = springs.force(x, v)
    with fast.use_backend("numba"):
        f, p = springs.force_and_power(x, v)
        f_only = springs.force(x, v)
    assert np.all(np.isfinite(f))
    assert close(f, f_ref) and close(f_only, f_ref_only) and close(p, p_ref)
    assert (p > 0) == damped


def test_force_model_rhs_and_energies_equal_system():
    scene = generators.cloth(6, 5, damping=0.3, gamma=0.2)
    system = scene.system
    rng = np.random.default_rng(1)
    x = scene.state0.x + 0.05 * rng.normal(size=scene.state0.x.shape)
    v = rng.normal(size=x.shape)
    model = fast.ForceModel(system)
    with fast.use_backend("numpy"):
        a_ref, p_ref = system.rhs(x, v)
        kin_ref, pot_ref = system.kinetic_energy(v), system.potential_energy(x)
    a, p = model.rhs(x, v)
    kin, pot = model.energies(x[None], v[None])
    assert close(a, a_ref) and close(p, p_ref)
    assert close(kin, [kin_ref]) and close(pot, [pot_ref])
    assert np.all(a[system.pinned] == 0.0)


def assert_same_run(a, b, tol=1e-12):
    assert a.complete == b.complete
    assert np.array_equal(a.t, b.t)
    assert close(a.x, b.x, tol) and close(a.v, b.v, tol)
    assert close(a.energy.kinetic, b.energy.kinetic, tol)
    assert close(a.energy.potential, b.energy.potential, tol)
    assert close(a.energy.dissipated, b.energy.dissipated, tol)
    sa, sb = a.stats.as_dict(), b.stats.as_dict()
    sa.pop("wall_time"), sb.pop("wall_time")
    assert sa == sb


SCENES = {
    "chain3d_damped": lambda: generators.chain(8, dim=3, stiffness=200.0, damping=0.4, gamma=0.1),
    "chain2d": lambda: generators.chain(6, dim=2),
    "cloth_damped": lambda: generators.cloth(5, 4, structural=50.0, shear=5.0, bend=1.0, damping=0.2,
                                              gamma=0.05),
    "oscillator1d": lambda: generators.oscillator(stiffness=4.0, gamma=0.3),
}


@pytest.mark.parametrize("method", FAST_METHODS)
@pytest.mark.parametrize("scene_name", list(SCENES))
def test_trajectory_equals_numpy_path(scene_name, method):
    scene = SCENES[scene_name]()
    runs = {b: mslab.simulate(scene, method, dt=2e-3, t_end=0.6, save_every=7, backend=b)
            for b in ("numpy", "numba")}
    assert_same_run(runs["numba"], runs["numpy"])
    m = mslab.get_method(method)
    if scene.system.velocity_dependent and m.family == "splitting":
        # each kick is a step of the splitting's kick method: its stages, every kick
        assert runs["numba"].stats.n_force == m.kick_method.n_stages * m.kick.size * 300
    else:
        assert runs["numba"].stats.n_force == m.n_stages * 300 + m.n_start


def test_energy_ledger_balances_on_the_fast_path():
    """Damped chain, rk4: K + U + D stays constant to the method's accuracy (an independent check)."""
    scene = generators.chain(8, dim=3, stiffness=200.0, damping=0.4, gamma=0.3)
    traj = mslab.simulate(scene, "rk4", dt=1e-3, t_end=2.0, save_every=100, backend="numba")
    assert traj.energy.dissipated[-1] > 0.01 * abs(traj.energy.total[0])
    assert np.max(np.abs(traj.energy.total - traj.energy.total[0])) < 1e-8


def test_chunk_boundaries_do_not_change_the_run(monkeypatch):
    scene = SCENES["chain3d_damped"]()
    whole = mslab.simulate(scene, "leapfrog", dt=2e-3, t_end=0.6, save_every=5, backend="numba")
    monkeypatch.setattr(fast.Stepper, "max_chunk", 7)
    pieces = mslab.simulate(scene, "leapfrog", dt=2e-3, t_end=0.6, save_every=5, backend="numba")
    assert_same_run(pieces, whole, tol=0.0)


def test_custom_tableau_runs_compiled():
    ralston = mslab.ExplicitRK([[0, 0], [2 / 3, 0]], [1 / 4, 3 / 4], name="ralston", order=2)
    scene = SCENES["chain3d_damped"]()
    assert fast.stepper(scene.system, ralston, "numba") is not None
    runs = [mslab.simulate(scene, ralston, dt=1e-3, t_end=0.3, backend=b) for b in ("numpy", "numba")]
    assert_same_run(runs[1], runs[0])


@pytest.mark.parametrize("method", ["rk4", "verlet"])
def test_blowup_is_the_same_instability_error(method):
    scene = generators.chain(6, dim=2, stiffness=1e4)
    errors = {}
    for b in ("numpy", "numba"):
        with pytest.raises(mslab.InstabilityError) as info:
            mslab.simulate(scene, method, dt=0.02, t_end=20.0, save_every=3, backend=b)
        errors[b] = info.value
    a, r = errors["numba"], errors["numpy"]
    assert (a.step, a.t, a.dt, a.method) == (r.step, r.t, r.dt, r.method)
    assert str(a) == str(r)
    assert_same_run(a.trajectory, r.trajectory, tol=1e-9)
    assert not a.trajectory.complete


def test_unsupported_scenes_fall_back_or_refuse():
    b = mslab.SceneBuilder(2)
    p = b.add_particle([0, 1], mass=1.0)
    q = b.add_particle([1, 1], mass=1.0)
    b.add_spring(p, q, 50.0)
    b.add_gravity([0, -9.81])
    b.add_plane(normal=[0, 1], offset=0.0, stiffness=1e4, friction=0.2)
    scene = b.build()
    assert fast.stepper(scene.system, mslab.get_method("rk4"), "auto") is None
    with pytest.raises(ValueError, match="no compiled kernel"):
        mslab.simulate(scene, "rk4", dt=1e-3, t_end=0.1, backend="numba")
    chain = generators.chain(4)
    with pytest.raises(ValueError, match="no compiled stepping loop"):
        mslab.simulate(chain, "implicit_euler", dt=1e-2, t_end=0.1, backend="numba")
    with pytest.raises(ValueError, match="unknown backend"):
        mslab.simulate(chain, "rk4", dt=1e-2, t_end=0.1, backend="cuda")
    runs = [mslab.simulate(scene, "rk4", dt=1e-3, t_end=0.3, backend=x) for x in ("numpy", "auto")]
    assert_same_run(runs[1], runs[0])


def test_wrapped_system_keeps_the_numpy_loop():
    """A System whose rhs was replaced (e.g. to log calls) is never bypassed."""
    scene = generators.chain(4)
    calls = []
    original = scene.system.rhs

    def logged(x, v):
        calls.append(1)
        return original(x, v)

    scene.system.rhs = logged
    traj = mslab.simulate(scene, "heun", dt=1e-2, t_end=0.1)
    assert len(calls) == traj.stats.n_force == 20


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_jacobian_fixed_pattern_equals_coo_assembly(dim):
    """Springs assemble into a CSR pattern built once; equal to pair_blocks (COO -> CSR) every call."""
    from mslab.effects.base import pair_blocks

    rng = np.random.default_rng(5 + dim)
    springs = random_springs(rng, n=9, m=25, dim=dim)
    for _ in range(3):  # the pattern of the first call is reused by the next ones
        blocks = rng.normal(size=(25, dim, dim))
        new, old = springs._assemble(blocks), pair_blocks(blocks, springs.i, springs.j, springs.n)
        assert new.shape == old.shape and new.has_sorted_indices
        assert np.array_equal(new.indptr, old.indptr) and np.array_equal(new.indices, old.indices)
        assert close(new.toarray(), old.toarray(), 1e-14)
    x, v = rng.normal(size=(9, dim)), rng.normal(size=(9, dim))
    K, D = springs.jacobians(x, v)
    eps = 1e-6  # and the assembled Jacobian is df/dx by central differences
    with fast.use_backend("numpy"):
        fd = np.column_stack([(springs.force(x + eps * e.reshape(x.shape), v)
                               - springs.force(x - eps * e.reshape(x.shape), v)).ravel() / (2 * eps)
                              for e in np.eye(x.size)])
    assert np.allclose(K.toarray(), fd, atol=1e-6 * max(1.0, np.abs(fd).max()))
