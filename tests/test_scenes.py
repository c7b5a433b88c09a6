"""Scene files: built-in scenes load, build exactly their declared effects, and run under every method;
the validator names the key of every kind of mistake."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
import scipy.linalg

import mslab
from mslab.effects import Damping, Gravity, Plane, Sphere, Springs
from mslab.errors import ConvergenceError, InstabilityError, SceneError
from mslab.scenes.loader import scene_path
from tests.scene_cases import BAD, BASE, bad_file

ISSUE_SCENES = ("pendulum", "chain", "hanging_rope", "stiff_chain", "mass_ratio", "cloth", "cloth_on_sphere",
                "jelly_cube", "cube_no_shear", "topology_pair")
EXPLICIT = tuple(m for m in mslab.methods() if mslab.get_method(m).explicit)
#: scenes built to show that explicit methods (and fixed-point iteration) fail at their default dt
MAY_FAIL = {"stiff_chain": EXPLICIT + ("implicit_euler_fp",), "cloth": EXPLICIT + ("implicit_euler_fp",)}


@pytest.fixture(scope="module")
def scenes():
    return {name: mslab.load_scene(name) for name in mslab.scene_names()}


def test_builtin_scenes_listed():
    assert set(ISSUE_SCENES) <= set(mslab.scene_names())
    for name in mslab.scene_names():
        text = scene_path(name).read_text()
        assert text.startswith("#"), f"{name}: the file should open with a comment on what it teaches"


@pytest.mark.parametrize("name", ISSUE_SCENES)
def test_declared_effects_are_built(name, scenes):
    """Effects listed in the file (read here with tomllib) are exactly the effects of the System."""
    doc = tomllib.loads(scene_path(name).read_text())
    bodies = doc.get("bodies", [{"springs": doc.get("springs")}])
    expected = []
    if any(b.get("springs") for b in bodies):
        expected.append("springs")
    if "gravity" in doc:
        expected.append("gravity")
    if doc.get("damping", {}).get("gamma", 0) > 0:
        expected.append("damping")
    expected += [c["type"] for c in doc.get("colliders", [])]
    assert sorted(scenes[name].effects) == sorted(expected)


@pytest.mark.parametrize("name", ISSUE_SCENES)
def test_every_method_runs_a_few_steps(name, scenes):
    scene = scenes[name]
    dt = scene.settings.dt
    for method in mslab.methods():
        try:
            traj = mslab.simulate(scene, method, t_end=5 * dt, check_stability=False, backend="numpy")
        except InstabilityError:
            assert method in MAY_FAIL.get(name, ()), f"{name} under {method} failed"
            continue
        assert traj.complete and traj.stats.steps == 5
        assert np.all(np.isfinite(traj.x))


def test_springs_only_scene_never_touches_other_effects(monkeypatch, scenes):
    """The chain lists only springs: gravity, drag and collider code must never run."""
    assert scenes["chain"].effects == ["springs"]

    def forbidden(*args, **kwargs):
        raise AssertionError("an effect the scene does not list was evaluated")

    for cls in (Gravity, Damping, Plane, Sphere):
        for attr in ("force", "energy", "power", "jacobians", "force_and_power", "__init__"):
            if hasattr(cls, attr):
                monkeypatch.setattr(cls, attr, forbidden)
    scene = mslab.load_scene("chain", t_end=0.02)
    for method in ("symplectic_euler", "rk4", "implicit_euler"):
        mslab.simulate(scene, method, check_stability=False, backend="numpy")


def test_stiff_chain_is_beyond_every_explicit_limit(scenes):
    """Fastest mode from the eigenvalues of M^-1 K (scipy, free particles): dt*w_max > 2*sqrt(2),
    beyond the largest explicit limit (rk4's); so explicit methods must blow up, Newton must not."""
    scene = scenes["stiff_chain"]
    system, x0 = scene.system, scene.state0.x
    K, _ = system.jacobians(x0, scene.state0.v)
    free = np.repeat(~system.pinned, system.dim)
    minv = np.repeat(1.0 / system.mass, system.dim)
    A = -(minv[:, None] * K.toarray())[np.ix_(free, free)]
    w_max = np.sqrt(np.max(scipy.linalg.eigvals(A).real))
    dt = scene.settings.dt
    assert dt * w_max > 2.0 * np.sqrt(2.0)
    for method in EXPLICIT:
        with pytest.raises(InstabilityError):
            mslab.simulate(scene, method, t_end=1.0, check_stability=False, backend="numpy")
    # fixed-point iteration contracts only while (dt w)^2 < 1
    with pytest.raises(ConvergenceError):
        mslab.simulate(scene, "implicit_euler_fp", t_end=0.1)
    traj = mslab.simulate(scene, "implicit_euler", t_end=0.5)
    assert traj.complete and np.all(np.isfinite(traj.x))


def test_generator_topology_counts(scenes):
    """Spring counts per kind from closed-form counts on a grid."""
    def counts(scene):
        kinds, n = np.unique(scene.spring_kind, return_counts=True)
        return dict(zip(kinds.tolist(), n.tolist(), strict=True))

    nx = ny = 10
    assert counts(scenes["cloth"]) == {"structural": 2 * nx * (ny - 1), "shear": 2 * (nx - 1) * (ny - 1),
                                       "bend": 2 * nx * (ny - 2)}
    n = 4
    face = 3 * 2 * (n - 1) ** 2 * n
    body = 4 * (n - 1) ** 3
    assert counts(scenes["jelly_cube"]) == {"structural": 3 * n * n * (n - 1), "shear": face + body}
    assert counts(scenes["cube_no_shear"]) == {"structural": 3 * n * n * (n - 1)}
    assert counts(scenes["chain"]) == {"structural": 9}
    # topology_pair: two 6x3 beams; the right one adds 2*(5*2) shear diagonals
    structural = 2 * (5 * 3 + 6 * 2)
    assert counts(scenes["topology_pair"]) == {"structural": structural, "shear": 2 * 5 * 2}


def test_loaded_values_match_the_file(scenes):
    cloth = scenes["cloth"]
    assert cloth.system.mass.sum() == pytest.approx(1.0)
    # top_corners: the two pinned particles are the corners of the top row (largest y, extreme x)
    x = cloth.state0.x
    pinned = np.flatnonzero(cloth.system.pinned)
    assert len(pinned) == 2
    assert np.allclose(x[pinned, 1], x[:, 1].max())
    assert sorted(x[pinned, 0]) == [x[:, 0].min(), x[:, 0].max()]
    g = [e for e in cloth.system.effects if e.name == "gravity"][0]
    assert np.allclose(g.force(x, x) / cloth.system.mass[:, None], [0.0, 0.0, -9.81])
    # rest lengths default to the initial lengths
    springs = cloth.springs()
    assert np.allclose(springs.lengths(x), springs.rest_length)
    ratio = scenes["mass_ratio"].system.mass
    assert ratio[1] / ratio[2] == pytest.approx(1e4)
    v = scenes["chain"].state0.v
    assert np.all(v[0] == 0.0) and np.allclose(v[1:], [0.0, 2.0])


def test_overrides():
    scene = mslab.load_scene("chain", dt=0.002, t_end=0.1, method="symplectic-euler", save_every=5)
    assert (scene.settings.dt, scene.settings.t_end, scene.settings.save_every) == (0.002, 0.1, 5)
    assert scene.settings.method == "symplectic_euler"
    with pytest.raises(SceneError, match="run.dt"):
        mslab.load_scene("chain", dt=-1.0)
    with pytest.raises(SceneError, match="whole number of steps"):
        mslab.load_scene("chain", dt=0.003)
    with pytest.raises(SceneError, match="valid methods"):
        mslab.load_scene("chain", method="rk5")
    with pytest.raises(SceneError, match="unknown override"):
        mslab.load_scene("chain", gravity=3.0)


def test_base_scene_is_valid(tmp_path):
    path = tmp_path / "base.toml"
    path.write_text(BASE)
    scene = mslab.load_scene(path)
    assert scene.effects == ["springs"] and scene.n_particles == 2
    assert scene.name == "base"


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_names_file_and_key(tmp_path, case):
    path, key, reason = bad_file(tmp_path, case)
    with pytest.raises(SceneError) as info:
        mslab.load_scene(path)
    err = info.value
    assert err.key == key
    assert reason in err.reason
    assert str(err).startswith(f"{path}: {key}: ")
    assert "\n" not in str(err)


def test_syntax_error_line_number(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(BASE + "\n[gravity]\ng = [0.0, -9.81\n")
    with pytest.raises(SceneError) as info:
        mslab.load_scene(path)
    assert info.value.key == f"line {BASE.count(chr(10)) + 3}"


def test_missing_scene_suggests_name():
    with pytest.raises(SceneError, match="did you mean 'cloth'"):
        mslab.load_scene("clth")


# ---- one rule for "down"; duplicates; folders; plural (effects branch) --------------------------------
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_down_is_one_rule(tmp_path, dim):
    """g = 9.81 in TOML, add_gravity(9.81) and the chain factory all pull along -y (2D), -z (3D), -x (1D)."""
    down = np.zeros(dim)
    down[-1] = -9.81
    b = mslab.SceneBuilder(dim)
    b.add_particle(np.zeros(dim))
    b.add_gravity(9.81)
    path = tmp_path / "g.toml"
    path.write_text(f"[scene]\ndim = {dim}\n[particles]\npositions = [{[0.0] * dim}]\n[gravity]\ng = 9.81\n")
    chain = mslab.scenes.chain(3, dim=dim, gravity=9.81)
    for scene in (b.build(), mslab.load_scene(path), chain):
        g = next(e for e in scene.system.effects if e.name == "gravity")
        np.testing.assert_array_equal(g.g, down)


def test_builtin_scenes_fall_down():
    """Every built-in scene with gravity pulls along -(last axis); the 3D cloth hangs along z."""
    for name in mslab.scene_names():
        scene = mslab.load_scene(name)
        for e in scene.system.effects:
            if e.name == "gravity":
                assert e.g[-1] < 0 and np.all(e.g[:-1] == 0), name


def test_duplicate_springs_in_the_builder():
    b = mslab.SceneBuilder(2)
    for x in ([0.0, 0.0], [1.0, 0.0], [1.0, 1.0]):
        b.add_particle(x)
    b.add_spring(0, 1, 10.0)
    with pytest.raises(SceneError, match=r"spring 1 \(\[1, 0\]\) joins the same two particles as spring 0"):
        b.add_spring(1, 0, 10.0)
    with pytest.raises(SceneError, match=r"spring 2 \(\[2, 1\]\) joins the same two particles as "
                                         r"spring 1 \(\[1, 2\]\)"):
        b.add_springs([[1, 2], [2, 1]], 5.0)
    assert b.build().springs().springs.tolist() == [[0, 1]]  # nothing half-added


def test_merged_duplicates_exert_the_force_of_both():
    """duplicates = "merge": one spring whose force equals the sum of the two (any rest lengths)."""
    rng = np.random.default_rng(4)
    x, v = rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
    b = mslab.SceneBuilder(3)
    b.add_particles(x)
    b.add_spring(0, 1, 30.0, rest_length=0.5, damping=0.2)
    q = b.add_spring(1, 0, 70.0, rest_length=1.5, damping=0.1, duplicates="merge")
    merged = b.build().springs()
    assert q == 0 and len(merged.springs) == 1
    two = Springs([[0, 1], [1, 0]], [30.0, 70.0], [0.5, 1.5], [0.2, 0.1], 2)
    np.testing.assert_allclose(merged.force(x, v), two.force(x, v), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(merged.jacobians(x, v)[0].toarray(), two.jacobians(x, v)[0].toarray(),
                               atol=1e-12)


def test_duplicate_springs_merge_in_toml(tmp_path):
    path = tmp_path / "merge.toml"
    path.write_text(BASE.replace("pairs = [[0, 1]]", 'pairs = [[0, 1], [1, 0]]\nduplicates = "merge"'))
    scene = mslab.load_scene(path)
    assert scene.springs().stiffness.tolist() == [200.0]


def test_duplicates_within_a_body_name_body_indices(tmp_path):
    text = """[scene]\ndim = 2\n[[bodies]]\npositions = [[0.0, 0.0], [1.0, 0.0]]\n[bodies.springs.structural]
pairs = [[0, 1]]\nstiffness = 1.0\n[[bodies]]\npositions = [[0.0, 1.0], [1.0, 1.0]]
[bodies.springs.structural]\npairs = [[0, 1], [1, 0]]\nstiffness = 1.0\n"""
    path = tmp_path / "bodies.toml"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        mslab.load_scene(path)
    assert info.value.key == "bodies[1].springs.structural.pairs[1]"
    assert "bodies[1].springs.structural.pairs[0] = [0, 1]" in info.value.reason


def test_a_folder_is_not_a_scene(tmp_path):
    with pytest.raises(SceneError, match="is a directory, not a scene file") as info:
        mslab.load_scene(tmp_path)
    assert "no built-in scene" not in str(info.value)


def test_size_text_is_singular_for_one():
    b = mslab.SceneBuilder(1)
    b.add_particle([0.0])
    b.add_particle([1.0])
    b.add_spring(0, 1, 1.0)
    assert b.build().size_text() == "2 particles, 1 spring"


def test_anchors_from_toml_default_to_initial_positions(tmp_path):
    path = tmp_path / "anchored.toml"
    path.write_text(BASE + "[anchors]\nparticles = [1]\nstiffness = 50.0\n")
    scene = mslab.load_scene(path)
    anchors = next(e for e in scene.system.effects if e.name == "anchors")
    np.testing.assert_array_equal(anchors.points, scene.state0.x[[1]])
    assert scene.effects == ["springs", "anchors"]


def test_generator_geometry_is_shared():
    """The Python factories and the scene-file generators place and pin particles identically."""
    from mslab.scenes.generators import generated_positions, pin_set

    cloth = mslab.scenes.cloth(5, 4)
    np.testing.assert_array_equal(cloth.state0.x, generated_positions("cloth", (4, 5), 3, size=(1.0, 1.0)))
    assert np.flatnonzero(cloth.system.pinned).tolist() == pin_set("cloth", "top_corners", (4, 5))
    chain = mslab.scenes.chain(4, dim=2, pin="both")
    assert np.flatnonzero(chain.system.pinned).tolist() == [0, 3]
