"""The compiled fast path (mslab.fast) equals the numpy reference: forces, trajectories, counters."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import mslab
from mslab import fast
from mslab.effects import Springs, effect_classes
from mslab.effects.base import Effect
from mslab.scenes import generators
from mslab.system import System

pytestmark = [
    # some runs below use methods outside their stability region on purpose (equality, blow-up)
    pytest.mark.filterwarnings("ignore::mslab.StabilityWarning"),
]

#: every registered method with a compiled loop (the registry decides, not this list)
FAST_METHODS = [m for m in mslab.methods() if mslab.get_method(m).compiled is not None]
#: every registered effect with a compiled kernel (the registry decides)
KERNEL_EFFECTS = [cls for cls in effect_classes() if cls.kernel is not None]
EFFECT_IDS = [c.name for c in KERNEL_EFFECTS] + ["all"]


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


def effect_scene(classes, dim: int, seed: int = 0):
    """6 particles in [-1, 1]^dim (one pinned) with each effect's ``example`` section, moving."""
    rng = np.random.default_rng(seed)
    b = mslab.SceneBuilder(dim)
    for n, xi in enumerate(rng.uniform(-1.0, 1.0, size=(6, dim))):
        b.add_particle(xi, mass=float(rng.uniform(0.5, 2.0)), velocity=rng.normal(size=dim), pinned=n == 3)
    for cls in classes:
        getattr(b, cls.builder_methods[0])(**cls.example(dim))
    return b.build()


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("cls", KERNEL_EFFECTS + [None], ids=EFFECT_IDS)
def test_composed_kernels_equal_system_rhs(cls, dim):
    """The generated sum of the effects' kernels (uint32 indices) equals System.rhs and System.force."""
    scene = effect_scene(KERNEL_EFFECTS if cls is None else [cls], dim)
    system = scene.system
    model = fast.ForceModel(system)
    rng = np.random.default_rng(dim)
    for _ in range(3):
        x = scene.state0.x + 0.3 * rng.normal(size=scene.state0.x.shape)
        v = rng.normal(size=x.shape)
        a_ref, p_ref = system.rhs(x, v)
        a, p = model.rhs(x, v)
        f, p2 = model.force(x, v)
        assert close(a, a_ref) and close(p, p_ref) and close(p2, p_ref)
        assert close(f, system.force(x, v))
        assert np.all(a[system.pinned] == 0.0)


@pytest.mark.parametrize("method", FAST_METHODS)
@pytest.mark.parametrize("cls", KERNEL_EFFECTS + [None], ids=EFFECT_IDS)
def test_every_kernel_effect_runs_compiled(cls, method):
    """Any scene whose effects all have kernels steps compiled, equal to numpy, same counters."""
    scene = effect_scene(KERNEL_EFFECTS if cls is None else [cls], 2, seed=3)
    assert fast.unsupported(scene.system, mslab.get_method(method)) is None
    runs = {b: mslab.simulate(scene, method, dt=1e-3, t_end=0.1, save_every=9, backend=b)
            for b in ("numpy", "numba")}
    assert_same_run(runs["numba"], runs["numpy"])


def assert_same_run(a, b, tol=1e-12):
    assert a.complete == b.complete
    assert np.array_equal(a.t, b.t)
    assert close(a.x, b.x, tol) and close(a.v, b.v, tol)
    assert close(a.energy.kinetic, b.energy.kinetic, tol)
    assert close(a.energy.potential, b.energy.potential, tol)
    assert close(a.energy.dissipated, b.energy.dissipated, tol)
    assert close(a.energy.external, b.energy.external, tol)
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
    elif not m.implicit:  # an implicit step's work depends on its iterations: equal counts checked above
        assert runs["numba"].stats.n_force == m.n_stages * 300 + m.n_start


#: built-in scenes with a penalty collider (the registry and the scene files decide)
COLLIDERS = {cls.name for cls in effect_classes() if cls.section == "colliders"}
COLLIDER_SCENES = [n for n in mslab.scene_names() if COLLIDERS & set(mslab.load_scene(n).effects)]


@pytest.mark.parametrize("scene_name", COLLIDER_SCENES)
def test_builtin_collider_scenes_run_compiled(scene_name):
    """Scenes with colliders step compiled, equal to numpy in contact; auto takes numba for long runs.

    Over their whole default runs the two paths part beyond 1e-12: stiff contact amplifies
    round-off (velocity differences grow by omega = sqrt(k/m) ~ 570/s at each impact, then
    exponentially: 1e-17 at 0.1 s, 1e-6 at 1.5 s in cube_no_shear's positions), so the
    equality is held over the first 0.3 s, which hold the first contacts.
    """
    scene = mslab.load_scene(scene_name)
    method = mslab.get_method(scene.settings.method)
    assert len(COLLIDER_SCENES) >= 2 and fast.unsupported(scene.system, method) is None
    runs = {b: mslab.simulate(scene, t_end=0.3, save_every=10, backend=b) for b in ("numpy", "numba")}
    assert_same_run(runs["numba"], runs["numpy"])
    contact = [e for e in scene.system.effects if e.name in COLLIDERS][0]
    assert sum(contact.energy(x) > 0.0 for x in runs["numpy"].x) >= 2  # the equality covers contact
    n_steps = round(scene.settings.t_end / scene.settings.dt)
    # auto: the default run (numpy measured 0.3-2 s) steps compiled (issue 38: every run of >= 0.2 s);
    # 100 steps (a few tens of ms in numpy) do not
    assert fast.worth_compiling(scene.system, method, n_steps)
    assert not fast.worth_compiling(scene.system, method, 100)
    assert fast.stepper(scene.system, method, "auto", n_steps=20 * n_steps, state0=scene.state0) is not None


def test_energy_ledger_balances_on_the_fast_path():
    """Damped chain, rk4: K + U + D stays constant to the method's accuracy (an independent check)."""
    scene = generators.chain(8, dim=3, stiffness=200.0, damping=0.4, gamma=0.3)
    traj = mslab.simulate(scene, "rk4", dt=1e-3, t_end=2.0, save_every=100, backend="numba")
    assert traj.energy.dissipated[-1] > 0.01 * abs(traj.energy.total[0])
    assert np.max(np.abs(traj.energy.total - traj.energy.total[0])) < 1e-8


@pytest.mark.parametrize("scene_name", ["chain3d_damped", "chain2d"])
@pytest.mark.parametrize("method", ["leapfrog", "velocity_verlet", "rk4", "forest_ruth"])
def test_chunk_boundaries_do_not_change_the_run(monkeypatch, method, scene_name):
    scene = SCENES[scene_name]()
    whole = mslab.simulate(scene, method, dt=2e-3, t_end=0.6, save_every=5, backend="numba")
    monkeypatch.setattr(fast.Stepper, "max_chunk", 7)
    pieces = mslab.simulate(scene, method, dt=2e-3, t_end=0.6, save_every=5, backend="numba")
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


class _Kick(Effect):
    """A constant push written without a kernel (an effect a user adds in numpy only)."""

    name = "kick"

    def force(self, x, v):
        return np.full_like(x, 0.5)

    def jacobians(self, x, v):
        return None, None


def test_unsupported_scenes_fall_back_or_refuse():
    b = mslab.SceneBuilder(2)
    p = b.add_particle([0, 1], mass=1.0)
    q = b.add_particle([1, 1], mass=1.0)
    b.add_spring(p, q, 50.0)
    b.add_gravity([0, -9.81])
    b.add_plane(normal=[0, 1], offset=0.0, stiffness=1e4, friction=0.2)
    built = b.build()
    system = System(built.system.mass, built.system.pinned, built.system.effects + (_Kick(),), 2)
    scene = dataclasses.replace(built, system=system)
    assert fast.stepper(scene.system, mslab.get_method("rk4"), "auto") is None
    with pytest.raises(ValueError, match=r"\['kick'\] have no compiled kernel"):
        mslab.simulate(scene, "rk4", dt=1e-3, t_end=0.1, backend="numba")
    chain = generators.chain(4)
    with pytest.raises(ValueError, match="no compiled stepping loop"):
        mslab.simulate(chain, "fast_mass_spring", dt=1e-2, t_end=0.1, backend="numba")
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
    fd = np.column_stack([(springs.force(x + eps * e.reshape(x.shape), v)
                           - springs.force(x - eps * e.reshape(x.shape), v)).ravel() / (2 * eps)
                          for e in np.eye(x.size)])
    assert np.allclose(K.toarray(), fd, atol=1e-6 * max(1.0, np.abs(fd).max()))


def _in_fresh_process(code: str, env: dict | None = None) -> str:
    import os
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900,
                         env={**os.environ, **(env or {})})
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_auto_runs_short_runs_in_numpy_without_loading_numba():
    """``backend="auto"``: a run too short to repay loading compiled code stays in numpy."""
    code = ("import sys, mslab; from mslab.scenes import generators; sc = generators.chain(4, dim=2); "
            "mslab.simulate(sc, 'rk4', dt=1e-3, t_end=0.05, check_stability=False); "
            "print('numba' in sys.modules)")
    assert _in_fresh_process(code) == "False"
    # 2000 steps: predicted 0.6 s in numpy, six times fast.AUTO_SECONDS (200 s of 1e5 steps cost
    # 10 s of stepping and decided nothing more)
    code = code.replace("t_end=0.05", "t_end=2.0")
    assert _in_fresh_process(code) == "True"


def test_import_mslab_loads_neither_scipy_nor_numba():
    """``import mslab`` stays cheap: scipy, numba and the stability package load on first use."""
    code = ("import sys, mslab; print(sorted(m for m in ('scipy', 'numba', 'mslab.stability', 'sympy') "
            "if m in sys.modules))")
    assert _in_fresh_process(code) == "[]"
    code = "import mslab; print(mslab.stability.imag_limit.__module__.startswith('mslab.stability'))"
    assert _in_fresh_process(code) == "True"


def test_constant_forces_are_summed_once():
    """Gravity is constant by the effect protocol (no Jacobian blocks): it leaves the kernels for f0."""
    scene = generators.chain(5, dim=3, stiffness=100.0, gamma=0.2)
    model = fast.ForceModel(scene.system)
    names = [k.__name__ for k in model.kernels]
    assert "gravity_kernel" not in names and "spring_kernel" in names and "damping_kernel" in names
    gravity = next(e for e in scene.system.effects if e.name == "gravity")
    assert np.array_equal(model.f0.T, gravity.force(scene.state0.x, scene.state0.v))  # (dim, n) in the loops


def test_index_parameters_are_narrowed_without_changing_values():
    """Non-negative indices reach the kernels as uint32 (no test for negative indices), others signed."""
    from mslab.fast.model import _param

    scene = generators.cloth(12, 12)  # rows of 11 springs: joined by gap springs (spring_batches.MIN_ROW)
    springs = next(e for e in scene.system.effects if e.name == "springs")
    model = fast.ForceModel(scene.system)
    params = model.params[[k.__name__ for k in model.kernels].index("spring_kernel")]
    i, j, gaps = params[0], params[1], params[10]
    assert i.dtype == j.dtype == gaps.dtype == np.uint32
    assert gaps.size > 0  # the cloth's rows joined by gap springs; the springs are the others
    assert np.array_equal(np.delete(i, gaps), springs.i) and np.array_equal(np.delete(j, gaps), springs.j)
    signed = _param(np.array([-1, 2**31 - 1]))
    assert signed.dtype == np.int32 and signed.tolist() == [-1, 2**31 - 1]
    assert _param(np.array([0, 2**32 - 1])).dtype == np.uint32
    assert _param(np.array([0, 2**32])).dtype == np.int64


@pytest.mark.slow
def test_generated_loops_are_cached_across_processes(tmp_path):
    """The composed module compiles once; a second process loads every loop from numba's cache.

    rk4's loop: its cold compile costs 13 s, the splitting loop's 20 s; both are cached alike."""
    code = ("import sys, mslab; from mslab.scenes import generators; "
            "sc = generators.chain(5, dim=3, gamma=0.1); "
            "mslab.simulate(sc, 'rk4', dt=1e-3, t_end=0.01, backend='numba'); "
            "mod = [m for n, m in sys.modules.items() if n.startswith('mslab_fast_')][0]; "
            "s = mod.run_explicit_rk.stats; print(sum(s.cache_hits.values()), sum(s.cache_misses.values()))")
    env = {"MSLAB_CACHE_DIR": str(tmp_path / "gen"), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    assert _in_fresh_process(code, env) == "0 1"  # compiled
    assert _in_fresh_process(code, env) == "1 0"  # loaded


def test_generated_loops_fall_back_to_a_temporary_folder(tmp_path, monkeypatch):
    """A cache folder that cannot be created (a file in the way) does not stop a run."""
    from mslab.fast import compose

    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("MSLAB_CACHE_DIR", str(blocker / "cache"))
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)  # re-read TMPDIR
    folder = compose.cache_dir()
    assert folder.is_dir() and str(folder).startswith(str(tmp_path / "tmp"))


def test_auto_decides_by_the_run_alone_not_by_history():
    """The same run takes the same backend whether or not compiled loops were loaded before.

    Both backends agree only to round-off, so a history-dependent choice would make printed
    results (lessons under nbval) change with what ran earlier in the process.
    """
    scene = generators.chain(6, dim=2)
    method = mslab.get_method("leapfrog")
    short = fast.worth_compiling(scene.system, method, 500)
    long = fast.worth_compiling(scene.system, method, 10**6)
    mslab.simulate(scene, method, dt=1e-3, t_end=0.01, backend="numba")  # loaded now
    again = tuple(fast.worth_compiling(scene.system, method, n) for n in (500, 10**6))
    assert again == (short, long) == (False, True)
