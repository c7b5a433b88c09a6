"""Effects: force = -grad(energy), Jacobians = finite differences, momentum, power; for every
registered effect: TOML round trip, compiled kernel = numpy, docs table; the docs' example effect."""

import re
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mslab
from mslab.effects import Damping, Gravity, Plane, Sphere, Springs, effect_classes, registry
from mslab.effects import docs as effect_docs
from mslab.errors import SceneError
from mslab.jit import compiled

ROOT = Path(__file__).resolve().parents[1]


def num_grad(fun, x, eps=1e-6):
    g = np.zeros_like(x)
    for idx in np.ndindex(x.shape):
        xp, xm = x.copy(), x.copy()
        xp[idx] += eps
        xm[idx] -= eps
        g[idx] = (fun(xp) - fun(xm)) / (2 * eps)
    return g


def num_jac(fun, x, eps=1e-6):
    """d fun(x) / dx for fun: (n, dim) -> (n, dim), as an (n*dim, n*dim) matrix."""
    cols = []
    for idx in np.ndindex(x.shape):
        xp, xm = x.copy(), x.copy()
        xp[idx] += eps
        xm[idx] -= eps
        cols.append(((fun(xp) - fun(xm)) / (2 * eps)).ravel())
    return np.array(cols).T


def dense(m, size):
    return np.zeros((size, size)) if m is None else m.toarray()


def check_effect(effect, x, v, conservative=True, rtol=1e-5, atol=1e-6):
    size = x.size
    if conservative:
        grad = num_grad(effect.energy, x)
        f0 = effect.force(x, np.zeros_like(v))
        np.testing.assert_allclose(f0, -grad, rtol=rtol, atol=atol)
    jx, jv = effect.jacobians(x, v)
    fd_x = num_jac(lambda y: effect.force(y, v), x)
    fd_v = num_jac(lambda w: effect.force(x, w), v)
    np.testing.assert_allclose(dense(jx, size), fd_x, rtol=rtol, atol=atol)
    np.testing.assert_allclose(dense(jv, size), fd_v, rtol=rtol, atol=atol)
    f, p = effect.force_and_power(x, v)
    np.testing.assert_allclose(f, effect.force(x, v))
    # the power an effect reports is what its non-conservative part removes, less what an
    # external drive (wind) puts in: P_D - P_W = -f_nc . v, P_D >= 0
    f_cons = effect.force(x, np.zeros_like(v)) if conservative else 0.0
    p_ext = effect.external_power(x, v)
    assert p - p_ext == pytest.approx(-np.sum((f - f_cons) * v), rel=1e-9, abs=1e-12)
    assert p >= 0.0
    # external work is the integral of external power: its rate along x + s v is P_W
    eps = 1e-6
    rate = (effect.external_work(x + eps * v, x) - effect.external_work(x - eps * v, x)) / (2 * eps)
    assert rate == pytest.approx(p_ext, rel=1e-6, abs=1e-9)
    assert effect.external_work(x, x) == 0.0
    if not effect.driving:
        assert p_ext == 0.0 and effect.external_work(x + v, x) == 0.0


@pytest.fixture
def rng():
    return np.random.default_rng(7)


def test_spring_matches_hooke_law_eq2():
    x = np.array([[0.0, 0.0], [3.0, 4.0]])
    s = Springs([[0, 1]], [10.0], [4.0], [0.0], 2)
    f = s.force(x, np.zeros_like(x))
    # f_0 = k (L - l) (x_0 - x_1)/l with l = 5, L = 4
    np.testing.assert_allclose(f[0], 10.0 * (4.0 - 5.0) * np.array([-3.0, -4.0]) / 5.0)
    np.testing.assert_allclose(f[1], -f[0])
    assert s.energy(x) == pytest.approx(0.5 * 10.0 * 1.0)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_springs_with_damping(rng, dim):
    n = 6
    x = rng.normal(size=(n, dim))
    v = rng.normal(size=(n, dim))
    pairs = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [0, 5], [1, 4]])
    s = Springs(pairs, rng.uniform(1, 10, 7), rng.uniform(0.2, 2, 7), rng.uniform(0, 2, 7), n)
    check_effect(s, x, v)
    np.testing.assert_allclose(s.force(x, v).sum(axis=0), 0.0, atol=1e-12)


def test_zero_length_spring_is_finite():
    x = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]])
    v = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    for rest in (0.0, 0.5):
        s = Springs([[0, 1]], [100.0], [rest], [1.0], 2)
        f, p = s.force_and_power(x, v)
        assert np.all(np.isfinite(f)) and np.isfinite(p) and np.isfinite(s.energy(x))
        jx, jv = s.jacobians(x, v)
        assert np.all(np.isfinite(jx.toarray())) and np.all(np.isfinite(jv.toarray()))


def test_zero_rest_length_spring_is_linear(rng):
    x = rng.normal(size=(2, 3))
    s = Springs([[0, 1]], [3.0], [0.0], [0.0], 2)
    np.testing.assert_allclose(s.force(x, x * 0)[0], -3.0 * (x[0] - x[1]))


def test_gravity_and_damping(rng):
    x = rng.normal(size=(4, 3))
    v = rng.normal(size=(4, 3))
    mass = rng.uniform(0.5, 2, 4)
    check_effect(Gravity([0, 0, -9.81], mass), x, v)
    check_effect(Damping(0.7, 4, 3), x, v, conservative=False)
    np.testing.assert_allclose(Damping(0.7, 4, 3).force(x, v), -0.7 * v)


@pytest.mark.parametrize("friction", [0.0, 0.4])
def test_plane_collider(rng, friction):
    x = rng.normal(size=(8, 3))
    v = rng.normal(size=(8, 3))
    plane = Plane([0.2, 1.0, 0.1], 0.0, 500.0, friction=friction, slip_velocity=0.3)
    assert np.any(x @ plane.normal < 0) and np.any(x @ plane.normal > 0)
    check_effect(plane, x, v)
    f = plane.force(x, v)
    outside = x @ plane.normal > 0
    np.testing.assert_array_equal(f[outside], 0.0)


@pytest.mark.parametrize("dim,friction", [(2, 0.0), (3, 0.0), (2, 0.5), (3, 0.5)])
def test_sphere_collider(rng, dim, friction):
    x = rng.normal(size=(10, dim)) * 0.8
    v = rng.normal(size=(10, dim))
    sphere = Sphere(np.zeros(dim) + 0.1, 1.0, 300.0, friction=friction, slip_velocity=0.2)
    check_effect(sphere, x, v)
    r = np.linalg.norm(x - 0.1, axis=1)
    np.testing.assert_array_equal(sphere.force(x, v)[r > 1.0], 0.0)


def test_friction_approaches_coulomb():
    x = np.array([[0.0, -0.01, 0.0]])
    v = np.array([[3.0, 0.0, 4.0]])
    plane = Plane([0, 1, 0], 0.0, 1000.0, friction=0.5, slip_velocity=1e-6)
    f = plane.force(x, v)[0]
    normal_force = 1000.0 * 0.01
    np.testing.assert_allclose(f[1], normal_force)
    np.testing.assert_allclose(f[[0, 2]], -0.5 * normal_force * np.array([3.0, 4.0]) / 5.0, rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_random_spring_networks(data):
    n = data.draw(st.integers(2, 7))
    dim = data.draw(st.integers(1, 3))
    seed = data.draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    x = rng.uniform(-2, 2, size=(n, dim))
    v = rng.normal(size=(n, dim))
    m = data.draw(st.integers(1, 12))
    i = rng.integers(0, n, m)
    j = (i + rng.integers(1, n, m)) % n
    pairs = np.stack([i, j], axis=1)
    lengths = np.linalg.norm(x[i] - x[j], axis=1)
    if lengths.min() < 0.05:
        return  # finite differences need a spring of non-vanishing length
    damped = data.draw(st.booleans())
    s = Springs(pairs, rng.uniform(0.1, 50, m), rng.uniform(0, 3, m),
                rng.uniform(0, 3, m) if damped else np.zeros(m), n)
    assert s.velocity_dependent == damped
    np.testing.assert_allclose(s.force(x, v).sum(axis=0), 0.0, atol=1e-9)
    check_effect(s, x, v, rtol=1e-4, atol=1e-5)


# ---- registry-wide contract: every registered effect, from its example section ---------------------
CLASSES = [cls for cls in effect_classes() if cls.section is not None]
DIMS = (1, 2, 3)
SEEDS = (3, 11)


def toml_text(doc: dict) -> str:
    """A small TOML writer for scene documents (tables, arrays of tables, numbers, strings, lists)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, list | tuple | np.ndarray):
            return "[" + ", ".join(value(u) for u in v) + "]"
        return repr(float(v)) if isinstance(v, float | np.floating) else str(int(v))

    lines = []

    def table(path, t):
        scalars = {k: v for k, v in t.items() if not isinstance(v, dict) and not _tables(v)}
        lines.extend(f"{k} = {value(v)}" for k, v in scalars.items())
        for k, v in t.items():
            if isinstance(v, dict):
                lines.append(f"[{path}{k}]")
                table(f"{path}{k}.", v)
            elif _tables(v):
                for item in v:
                    lines.append(f"[[{path}{k}]]")
                    table(f"{path}{k}.", item)

    table("", doc)
    return "\n".join(lines) + "\n"


def _tables(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(u, dict) for u in v)


def random_particles(dim: int, seed: int):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1.0, 1.0, size=(6, dim))
    mass = rng.uniform(0.5, 2.0, size=6)
    return x, mass


def built_effect(cls, dim: int, seed: int):
    """The effect made by the builder method from ``example(dim)``, with random x, v."""
    x, mass = random_particles(dim, seed)
    b = mslab.SceneBuilder(dim)
    for xi, m in zip(x, mass, strict=True):
        b.add_particle(xi, mass=float(m))
    getattr(b, cls.builder_methods[0])(**cls.example(dim))
    scene = b.build()
    effects = [e for e in scene.system.effects if type(e) is cls]
    assert len(effects) == 1, f"{cls.name}: example built {len(effects)} effects"
    v = np.random.default_rng(seed + 1).normal(size=x.shape)
    return effects[0], x, v, scene


def effect_cases():
    return [pytest.param(cls, dim, seed, id=f"{cls.name}-{dim}d-{seed}") for cls in CLASSES for dim in DIMS
            for seed in SEEDS]


@pytest.mark.parametrize("cls,dim,seed", effect_cases())
def test_registered_effect_contract(cls, dim, seed):
    """force = -grad U, power = work of the velocity terms >= 0, Jacobians = finite differences, momentum."""
    effect, x, v, _ = built_effect(cls, dim, seed)
    check_effect(effect, x, v, conservative=effect.conservative)
    if not effect.dissipative:
        assert effect.power(x, v) == 0.0
    if cls.internal:
        np.testing.assert_allclose(effect.force(x, v).sum(axis=0), 0.0, atol=1e-12)


@pytest.mark.parametrize("cls", CLASSES, ids=[c.name for c in CLASSES])
@pytest.mark.parametrize("dim", DIMS)
def test_toml_round_trip(tmp_path, cls, dim):
    """The example section in a scene file builds the same effect as the builder method."""
    effect, x, v, scene = built_effect(cls, dim, 5)
    x0, mass = random_particles(dim, 5)
    doc = {"scene": {"dim": dim}, "particles": {"positions": x0.tolist(), "mass": mass.tolist()}}
    doc.update(cls.toml_fragment(cls.example(dim)))
    path = tmp_path / f"{cls.name}.toml"
    path.write_text(toml_text(doc))
    loaded = mslab.load_scene(path)
    assert loaded.effects == scene.effects == [cls.name]
    twin = loaded.system.effects[0]
    np.testing.assert_array_equal(twin.force(x, v), effect.force(x, v))
    assert twin.energy(x) == effect.energy(x) and twin.power(x, v) == effect.power(x, v)
    assert twin.external_work(x + v, x) == effect.external_work(x + v, x)
    for a, b in zip(twin.jacobians(x, v), effect.jacobians(x, v), strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_array_equal(a.toarray(), b.toarray())


KERNEL_CLASSES = [cls for cls in CLASSES if cls.kernel is not None]


@pytest.mark.parametrize("cls", KERNEL_CLASSES, ids=[c.name for c in KERNEL_CLASSES])
@pytest.mark.parametrize("dim", DIMS)
def test_kernel_equals_numpy(cls, dim):
    pytest.importorskip("numba")
    kernel = compiled(cls.kernel)  # the one way mslab compiles (helpers, prange)
    for seed in SEEDS:
        effect, x, v, _ = built_effect(cls, dim, seed)
        params = effect.kernel_params()
        for p in params:
            if isinstance(p, np.ndarray):
                assert p.dtype in (np.float64, np.int64) and p.flags.c_contiguous, (cls.name, p.dtype)
            else:
                assert isinstance(p, int | float) and not isinstance(p, bool)
        f_ref, p_ref = effect.force_and_power(x, v)
        scale = max(1.0, float(np.max(np.abs(f_ref))))
        for rows in (False, True):  # particle-major memory, and the compiled loops' coordinate rows
            xk, vk = (np.ascontiguousarray(a.T).T for a in (x, v)) if rows else (x, v)
            f = np.zeros_like(xk)  # (the same layout as xk)
            power = kernel(xk, vk, f, *params)
            assert np.max(np.abs(f - f_ref)) <= 1e-12 * scale, (cls.name, rows)
            assert abs(power - p_ref) <= 1e-12 * max(1.0, abs(p_ref))


def test_springs_kernel_zero_length_and_undamped():
    pytest.importorskip("numba")
    kernel = compiled(Springs.kernel)  # the one way mslab compiles (helpers, prange)
    rng = np.random.default_rng(2)
    for dim in DIMS:
        for damped in (False, True):
            x, v = rng.normal(size=(8, dim)), rng.normal(size=(8, dim))
            pairs = np.array([[0, 1], [1, 2], [2, 3], [4, 5], [5, 6], [6, 7], [0, 7]])
            x[5] = x[4]  # a spring of zero length: no force, no NaN
            s = Springs(pairs, rng.uniform(1, 100, 7), rng.uniform(0.1, 2, 7),
                        rng.uniform(0, 3, 7) if damped else np.zeros(7), 8)
            f = np.zeros_like(x)
            p = kernel(x, v, f, *s.kernel_params())
            f_ref, p_ref = s.force_and_power(x, v)
            assert np.all(np.isfinite(f)) and np.max(np.abs(f - f_ref)) <= 1e-12 * np.max(np.abs(f_ref))
            assert abs(p - p_ref) <= 1e-12 * max(1.0, p_ref) and (p > 0) == damped


@pytest.mark.parametrize("friction", [0.0, 0.5])
def test_collider_kernel_edge_cases(friction):
    """One kernel for both colliders: a particle at the sphere's centre, on the plane, outside, at rest."""
    pytest.importorskip("numba")
    kernel = compiled(Plane.kernel)  # the one way mslab compiles (helpers, prange)
    assert Sphere.kernel is Plane.kernel
    rng = np.random.default_rng(4)
    for dim in DIMS:
        x, v = rng.uniform(-1, 1, size=(7, dim)), rng.normal(size=(7, dim))
        centre = np.full(dim, 0.1)
        x[0] = centre  # r = 0: depth = radius, normal undefined: no force (as numpy)
        x[1] = centre + 0.999 * np.eye(dim)[0]  # just inside
        v[2] = 0.0  # at rest: smooth friction gives 0, not NaN
        normal = np.eye(dim)[-1]
        x[3] = 0.05 * np.eye(dim)[0] + 0.2 * normal  # exactly on the plane n . x = 0.2: no contact
        for effect in (Sphere(centre, 1.0, 300.0, friction=friction, slip_velocity=0.2),
                       Plane(normal, 0.2, 500.0, friction=friction, slip_velocity=0.3)):
            f = np.zeros_like(x)
            p = kernel(x, v, f, *effect.kernel_params())
            f_ref, p_ref = effect.force_and_power(x, v)
            assert np.all(np.isfinite(f)) and np.max(np.abs(f - f_ref)) <= 1e-12 * np.max(np.abs(f_ref))
            assert abs(p - p_ref) <= 1e-12 * max(1.0, p_ref)
            assert p == 0.0 if friction == 0.0 else (p > 0.0 or dim == 1)  # 1D: no tangent to slide along
            assert np.count_nonzero(f.any(axis=1)) >= 2  # some particles are in contact
        assert np.all(f[3] == 0.0)


def test_docs_hold_the_generated_tables():
    text = (ROOT / "docs" / "scenes.md").read_text()
    assert effect_docs.effect_tables() in text, "regenerate: python -m mslab.effects.docs docs/scenes.md"


def test_anchor_spring_is_hookes_law_to_a_fixed_point():
    """f = -k (x - a) exactly, energy k |x - a|^2 / 2, and a bob on an anchor oscillates at sqrt(k/m)."""
    b = mslab.SceneBuilder(2)
    b.add_particle([0.3, 0.0], mass=2.0, velocity=[0.0, 0.0])
    b.add_anchors([0], stiffness=8.0, points=[[0.0, 0.0]])
    scene = b.build()
    anchors = scene.system.effects[0]
    x = np.array([[0.3, -0.4]])
    np.testing.assert_allclose(anchors.force(x, x), [[-8.0 * 0.3, 8.0 * 0.4]])
    assert anchors.energy(x) == pytest.approx(0.5 * 8.0 * 0.25)
    # w = sqrt(k / m) = 2: half a period at t = pi / 2
    tr = mslab.simulate(scene, "rk4", dt=np.pi / 2000, t_end=np.pi / 2, check_stability=False)
    np.testing.assert_allclose(tr.x[-1, 0], [-0.3, 0.0], atol=1e-9)


# ---- the example of docs/extending.md, copied into a folder the registry scans ----------------------
def _doc_block(lang: str, section: str = "## Adding an effect") -> str:
    text = (ROOT / "docs" / "extending.md").read_text()
    text = text[text.index(section):]
    return re.search(rf"```{lang}\n(.*?)```", text, re.S).group(1)


def test_extending_example(tmp_path, monkeypatch):
    import mslab.effects as package

    folder = tmp_path / "more_effects"
    folder.mkdir()
    (folder / "loads.py").write_text(_doc_block("python"))
    monkeypatch.setattr(package, "__path__", [*package.__path__, str(folder)])
    try:
        registry.discover()
        cls = registry.get_effect("loads")
        scene_file = tmp_path / "loaded_rope.toml"
        scene_file.write_text(_doc_block("toml"))
        scene = mslab.load_scene(scene_file)
        assert scene.effects == ["springs", "loads"]
        loads = scene.system.effects[1]
        np.testing.assert_array_equal(loads.force(scene.state0.x, scene.state0.v)[4], [0.0, -2.0])
        # the registry-wide checks, on the new effect
        for dim in DIMS:
            test_registered_effect_contract(cls, dim, 3)
            test_toml_round_trip(tmp_path, cls, dim)
            test_kernel_equals_numpy(cls, dim)
        assert "`[loads]`" in effect_docs.effect_tables()
        # a mistake in its section is one line naming the key
        scene_file.write_text(_doc_block("toml").replace("force = [0.0, -2.0]", "force = [0.0, -2.0, 1.0]"))
        with pytest.raises(SceneError, match=r"loaded_rope.toml: loads.force: must be a list of 2 numbers"):
            mslab.load_scene(scene_file)
        tr = mslab.simulate(scene, t_end=0.05)
        assert tr.complete
    finally:
        registry._registry.pop("loads", None)
        registry._imported.discard("loads")
        sys.modules.pop("mslab.effects.loads", None)


@pytest.mark.parametrize("cls", CLASSES, ids=[c.name for c in CLASSES])
@pytest.mark.parametrize("dim", DIMS)
def test_energies_of_many_states_are_each_states_energy_bitwise(cls, dim):
    """``energies(xs)`` (the ledger's samples at once) equals ``energy(x)`` state by state, bit for bit."""
    effect, x, _, _ = built_effect(cls, dim, 3)
    xs = x[None] + np.random.default_rng(7).normal(scale=0.3, size=(5,) + x.shape)
    got = effect.energies(xs)
    assert got.shape == (5,)
    assert got.tobytes() == np.array([effect.energy(s) for s in xs]).tobytes()


def test_ledger_energies_of_a_big_cloth_bitwise():
    """Thousands of terms per state (numpy's pairwise blocks): the sums state by state, not over an axis."""
    scene = mslab.scenes.generators.cloth(30, 30, structural=100.0, shear=10.0, bend=1.0, gravity=9.81)
    system = scene.system
    rng = np.random.default_rng(0)
    xs = scene.state0.x[None] + rng.normal(scale=0.01, size=(4,) + scene.state0.x.shape)
    vs = rng.normal(size=xs.shape)
    one_by_one = np.array([system.potential_energy(x) for x in xs])
    assert system.potential_energies(xs).tobytes() == one_by_one.tobytes()
    assert system.kinetic_energies(vs).tobytes() == np.array([system.kinetic_energy(v) for v in vs]).tobytes()
    # the sum over an axis of the whole array is not the same sum (so the test above can fail)
    springs = next(e for e in system.effects if isinstance(e, Springs))
    d = xs[:, springs.i] - xs[:, springs.j]
    terms = springs.stiffness * (np.sqrt(np.einsum("kij,kij->ki", d, d)) - springs.rest_length) ** 2
    assert (0.5 * terms.sum(axis=1)).tobytes() != springs.energies(xs).tobytes()


@pytest.mark.parametrize("base", [Springs, Gravity], ids=["springs", "gravity"])
def test_a_subclass_with_its_own_energy_keeps_it_in_the_ledger(base):
    """A subclass that redefines ``energy`` (a careless extension) is not given the base class's batch."""
    cls = type("Doubled", (base,), {"energy": lambda self, x: 2.0 * base.energy(self, x)})
    effect, x, _, _ = built_effect(base, 2, 4)
    twin = object.__new__(cls)
    twin.__dict__.update(effect.__dict__)
    xs = x[None] + np.random.default_rng(2).normal(scale=0.1, size=(3,) + x.shape)
    assert twin.energies(xs).tolist() == [2.0 * effect.energy(s) for s in xs]
    assert effect.energies(xs).tolist() == [effect.energy(s) for s in xs]
    assert twin.compiled_energy(x) == 2.0 * effect.energy(x)  # the compiled ledger check's energy too
