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


# -- D5, D6, D8: arguments checked before use, one error naming each -----------------------------
@pytest.mark.parametrize(("call", "error", "text"), [
    (lambda sc: mslab.simulate("chain"), TypeError, r"scene must be an mslab Scene .*load_scene\('chain'\)"),
    (lambda sc: mslab.simulate(None), TypeError, "scene must be an mslab Scene"),
    (lambda sc: mslab.simulate(sc, t_end=0.01, progress="yes"), TypeError, "progress must be"),
    (lambda sc: mslab.Simulation(sc, "rk4", 1e-3).advance(3, progress=5), TypeError, "progress must be"),
    (lambda sc: mslab.simulate(sc, dt=10**400), ValueError, "dt must be a finite number"),
    (lambda sc: mslab.simulate(sc, t_end=10**400), ValueError, "t_end must be a finite number"),
    (lambda sc: mslab.simulate(sc, blowup=10**400), ValueError, "blowup must be a finite number"),
    (lambda sc: mslab.Simulation(sc, t_end=10**400), ValueError, "t_end must be a finite number"),
    (lambda sc: mslab.load_scene("chain", dt=10**400), mslab.SceneError, r"run\.dt: must be a finite number"),
    (lambda sc: mslab.load_scene("chain", max_bytes=-1), ValueError, "max_bytes must be >= 1"),
    (lambda sc: mslab.load_scene("chain", max_bytes=True), TypeError, "max_bytes must be a whole number"),
    (lambda sc: mslab.load_scene("chain", max_bytes="1G"), TypeError, "max_bytes must be a whole number"),
])
def test_bad_arguments_give_one_error_naming_them(call, error, text):
    with pytest.raises(error, match=text) as info:
        call(chain())
    assert "\n" not in str(info.value) and len(str(info.value)) < 300


def test_progress_is_checked_before_the_set_up(monkeypatch):
    from mslab import simulation

    monkeypatch.setattr(simulation.Simulation, "__init__", lambda *a, **k: pytest.fail("set-up started"))
    with pytest.raises(TypeError, match="progress"):
        mslab.simulate(chain(), t_end=0.01, progress="yes")


def test_overrides_are_plain_floats():
    settings = mslab.load_scene("chain", t_end=np.float64(2), dt=np.float64(1e-3)).settings
    assert type(settings.t_end) is float and type(settings.dt) is float and settings.t_end == 2.0


# -- D9: a huge scene file is refused by its size, before it is read ------------------------------
def test_a_huge_scene_file_is_refused_before_parsing(tmp_path, capsys):
    import time

    from mslab.cli import main
    from mslab.scenes.toml_read import MAX_FILE_BYTES

    path = tmp_path / "huge.toml"
    entries = MAX_FILE_BYTES // len("[0.0, 0.0], ") + 10
    path.write_text("[particles]\npositions = [" + "[0.0, 0.0], " * entries + "]\n")
    begun = time.perf_counter()
    with pytest.raises(mslab.SceneError, match=r"file: .*MiB, more than the 8 MiB") as info:
        mslab.load_scene(path)
    assert time.perf_counter() - begun < 0.5 and "generator" in str(info.value)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"mslab: error: {path}: file: ")


# -- D10: --jobs beyond the CPUs is capped to them -----------------------------------------------
def test_jobs_beyond_the_cpus_are_capped(monkeypatch, capsys):
    import importlib

    from mslab import precision
    from mslab.cli import main

    wp = importlib.import_module("mslab.precision.work_precision")  # the module, not the function
    from mslab.scenes import oscillator

    pools: list[int] = []
    real_run = wp._run_tasks
    monkeypatch.setattr(wp, "usable_cpus", lambda: 1, raising=False)
    monkeypatch.setattr(wp, "_run_tasks", lambda tasks, jobs, bar: pools.append(jobs) or real_run(tasks, jobs,
                                                                                                   bar))
    records = precision.work_precision(oscillator(), ["rk4"], [0.1, 0.05], t_end=1.0, timing=False, jobs=300)
    assert len(records) == 2 and max(pools) == 1
    from mslab.precision import runs

    monkeypatch.setattr(runs, "usable_cpus", lambda: 1, raising=False)
    assert main(["precision", "oscillator", "--methods", "rk4", "--t-end", "1", "--dts", "0.1", "0.05",
                 "--scipy", "--no-timing", "--jobs", "300", "--json"]) == 0
    assert '"jobs": 1' in capsys.readouterr().out


# -- D14: a reader that leaves early (mslab methods | head) ends the command quietly ---------------
def test_a_broken_pipe_ends_quietly():
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    read, write = os.pipe()
    os.close(read)  # the reader is gone before mslab writes a line
    try:
        done = subprocess.run([sys.executable, "-m", "mslab", "methods"], stdout=write,
                              stderr=subprocess.PIPE, text=True, timeout=300,
                              env={**os.environ, "PYTHONPATH": str(root)})
    finally:
        os.close(write)
    assert done.stderr == "" and done.returncode == 141


# -- D11, D12, D13: step counts beyond float64, messages about the argument given ----------------
def test_advance_beyond_what_a_run_can_count_is_refused():
    sim = mslab.Simulation(chain(), "rk4", 1e-3)
    with pytest.raises(ValueError, match="more than a run can count exactly"):
        sim.advance(2**53 + 1)
    assert sim.step == 0


def test_advance_t_messages_name_t_and_suggest_a_time():
    sim = mslab.Simulation(chain(), "rk4", 1e-3)
    with pytest.raises(ValueError, match=r"^t = 0\.0105 is not a whole number .*; use t = 0\.01 \(10 st"):
        sim.advance(t=0.0105)
    with pytest.raises(ValueError, match=r"^t = 1e\+300 is .*more than a run can count"):
        sim.advance(t=1e300)


def test_a_dt_close_to_a_valid_one_is_shown_with_its_digits():
    with pytest.raises(ValueError) as info:
        mslab.simulate(chain(), dt=np.float32(1e-3), t_end=0.01)
    given, use = str(info.value).split("; use ")
    assert "0.0010000000474974513" in given and use == "dt = 0.001 (10 steps)"


# -- D15: reprs are one-line summaries ------------------------------------------------------------
def test_state_energy_and_session_reprs_are_one_line():
    cloth = mslab.load_scene("cloth")
    sim = mslab.Simulation(cloth, "verlet", cloth.settings.dt / 8, backend="numpy")
    sim.advance(2)
    for obj in (sim, sim.state, sim.trajectory.energy):
        text = repr(obj)
        assert "\n" not in text and len(text) < 200 and " at 0x" not in text, text
    assert repr(sim).startswith("Simulation('cloth': verlet")


# -- D16: small corner cases of options and names -------------------------------------------------
def test_python_digit_separators_are_no_command_line_number(capsys):
    from mslab.cli import main

    for option in (["--dt", "1_000"], ["--save-every", "1_0"]):
        assert main(["run", "chain", *option]) == 2
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1 and "must be a" in err[0] and "1_0" in err[0], err


@pytest.mark.parametrize("char", ["\u202e", "\u200b", "\u2028", "\x85"])
def test_a_scene_name_with_an_invisible_character_is_refused(char):
    from mslab.files import file_stem, name_problem

    assert "U+" in name_problem(f"a{char}b")
    with pytest.raises(ValueError, match="scene name"):
        file_stem(f"a{char}b")
    assert name_problem("my scene: é") is None


@pytest.mark.parametrize("call, error, words", [
    (lambda b: b.add_particle(["3", "4"]), TypeError, "position must be real numbers"),
    (lambda b: b.add_particle([0.0, 0.0], pinned="no"), TypeError, "pinned must be True or False"),
    (lambda b: b.add_particle(np.array([1 + 2j, 0])), TypeError, "position must be real numbers"),
    (lambda b: b.add_particle([0.0, 0.0], mass=True), TypeError, "mass must be a number"),
    (lambda b: b.add_particle([True, False]), TypeError, "position must be real numbers"),
    (lambda b: b.add_particle([0.0, 0.0], mass="1"), TypeError, "mass must be a number"),
    (lambda b: b.add_particle([0.0, 0.0], mass=1j), TypeError, "mass must be a number"),
    (lambda b: b.add_particle([10**400, 0]), ValueError, "position: must be finite numbers"),
    (lambda b: b.add_particle([0.0, 0.0], velocity=["1", "0"]), TypeError, "velocity must be real numbers"),
    (lambda b: b.add_particles([[0.0, 0.0], [1.0, 1.0]], mass=["a", "b"]), TypeError, "mass must be real"),
    (lambda b: mslab.SceneBuilder(dim=True), TypeError, "dim must be a whole number"),
    (lambda b: mslab.SceneBuilder(dim=2.0), TypeError, "dim must be a whole number"),
])
def test_the_scene_builder_converts_nothing_silently(call, error, words):
    """Text, bools and complex numbers were converted without a word (pinned="no" pinned a particle,
    1+2j lost its imaginary part): each is refused in one error naming the argument, as the file
    loader refuses them."""
    b = mslab.SceneBuilder(dim=2)
    with pytest.raises(error, match=words):
        call(b)
    b.add_particle([0.0, 0.0])                 # nothing of the refused call was added
    assert b.build().state0.x.shape == (1, 2)


def test_the_scene_builder_takes_numpy_numbers():
    b = mslab.SceneBuilder(dim=2)
    assert b.add_particle(np.zeros(2, dtype=np.float32), mass=np.float64(2.0), pinned=np.bool_(True)) == 0
    assert list(b.add_particles(np.ones((3, 2), dtype=np.int64), mass=np.arange(1, 4))) == [1, 2, 3]
