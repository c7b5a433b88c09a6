"""Hostile scene files and outputs: each ends in one line and exit 2 before anything is computed.

Every case runs ``mslab validate`` and ``mslab run`` in-process with the stepping loop
replaced by a tripwire (nothing may be simulated), and checks the one line on stderr, the
exit code and that no output folder appeared.
"""

from __future__ import annotations

import errno
import importlib
import os
from pathlib import Path

import numpy as np
import pytest

import mslab
from mslab.cli import main
from mslab.scenes.loader import SCENE_DIR

PENDULUM = (SCENE_DIR / "pendulum.toml").read_text()


def _tripwire(monkeypatch):
    """Make any simulation fail the test: a refusal must come before anything is computed."""
    import mslab.budget
    import mslab.commands.run

    def boom(*args, **kwargs):
        raise AssertionError("a run started")

    monkeypatch.setattr(mslab.commands.run, "predicted_dt", boom)
    monkeypatch.setattr(importlib.import_module("mslab.simulate"), "simulate", boom)  # the module's
    monkeypatch.setattr(mslab.budget, "time_per_step", boom)


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _one_line(capsys, argv: list[str]) -> str:
    code = main(argv)
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("mslab: error: "), (code, err)
    assert "Traceback" not in err and out == ""
    return lines[0]


def _files(tmp_path: Path) -> dict[str, tuple[Path, str, str]]:
    """name -> (scene file, key the line names, words of the reason)."""
    deep = "[" * 3000 + "1.0" + "]" * 3000
    cases = {
        "deep": (PENDULUM.replace("mass = 1.0 ", f"mass = {deep} "), "line 13", "nested more than 16 deep"),
        "huge_cloth": ('[scene]\nname = "huge"\ndim = 3\n[particles]\ngenerator = "cloth"\nnx = 100000\n'
                       'ny = 100000\n[springs.structural]\nstiffness = 100.0\n',
                       "particles.generator", "1e+10 particles would need at least 447 GB"),
        "far_positions": (PENDULUM.replace("[1.0, 0.0]]", "[1e300, 0.0]]"), "particles.positions[1][0]",
                          "1e+300 is beyond +-1e+150"),
        "stiff": (PENDULUM.replace("stiffness = 1000.0", "stiffness = 1e308"), "springs.structural.stiffness",
                  "1e+308 is beyond +-1e+150"),
        "huge_integer": (PENDULUM.replace("mass = 1.0 ", f"mass = {10**200} "), "particles.mass",
                         "an integer of 201 digits is beyond"),
        # each value fits, but K = m v^2 / 2 = 1e320 does not
        "together": (PENDULUM.replace("mass = 1.0 ", "mass = 1e100\nvelocity = [0.0, 1e110] "),
                     "scene", "the initial energy overflow"),
        "tiny_dt": (PENDULUM.replace("dt = 0.001", "dt = 1e-300"), "run.dt",
                    "give 4e+300 steps, more than 1e+12"),
    }
    return {name: (_write(tmp_path, name, text), key, words) for name, (text, key, words) in cases.items()}


@pytest.mark.parametrize("command", ["validate", "run"])
@pytest.mark.parametrize("case", ["deep", "huge_cloth", "far_positions", "stiff", "huge_integer", "together",
                                  "tiny_dt"])
def test_hostile_scene_files_end_in_one_line(tmp_path, monkeypatch, capsys, command, case):
    _tripwire(monkeypatch)
    path, key, words = _files(tmp_path)[case]
    out = tmp_path / "out"
    extra = ["--out", str(out)] if command == "run" else ["--no-timing"]
    line = _one_line(capsys, [command, str(path), *extra, "--max-memory", "8G"])
    assert f"{path}: {key}: " in line and words in line, line
    assert len(line) < 400 and not out.exists()


def test_special_files_are_named_for_what_they_are(tmp_path, monkeypatch, capsys):
    _tripwire(monkeypatch)
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    loop = tmp_path / "loop.toml"
    loop.symlink_to(loop)
    dangling = tmp_path / "gone.toml"
    dangling.symlink_to(tmp_path / "nowhere.toml")
    for path, words in ((fifo, "is a named pipe (FIFO), not a regular file"),
                        (loop, "is a symbolic link that leads back to itself"),
                        (dangling, "which does not exist")):
        for command in ("validate", "run"):
            line = _one_line(capsys, [command, str(path)])
            assert words in line and "no built-in scene" not in line


def test_a_utf8_byte_order_mark_is_read(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_text(PENDULUM, encoding="utf-8-sig")
    assert path.read_bytes()[:3] == b"\xef\xbb\xbf"
    assert mslab.load_scene(path).n_particles == 2


def test_nesting_inside_strings_and_comments_does_not_count(tmp_path):
    text = PENDULUM.replace('description = "', 'description = "' + "[" * 40).replace(
        "# anchor, bob", "# " + "[" * 40 + " anchor, bob")
    assert mslab.load_scene(_write(tmp_path, "brackets", text)).n_particles == 2


# -- --out, checked before the run --------------------------------------------------------------------
def test_out_that_is_a_file_is_refused_before_the_run(tmp_path, monkeypatch, capsys):
    _tripwire(monkeypatch)
    target = tmp_path / "results"
    target.write_text("not a folder")
    assert "--out: " in _one_line(capsys, ["run", "pendulum", "--out", str(target)])
    line = _one_line(capsys, ["run", "pendulum", "--out", str(target / "sub")])
    assert f"{target} is a file, so the folder {target / 'sub'} cannot be made" in line


def test_validate_refuses_an_out_it_could_not_save_to_before_any_work(tmp_path, monkeypatch, capsys):
    """`validate --out` checks the folder first, as `run` does (issue 37): it used to check every scene
    (timed steps included) and only then fail at saving."""
    import mslab.commands.validate

    _tripwire(monkeypatch)
    monkeypatch.setattr(mslab.commands.validate, "check", lambda *a, **k: (_ for _ in ()).throw(
        AssertionError("a scene was checked")))
    target = tmp_path / "results"
    target.write_text("not a folder")
    assert "--out: " in _one_line(capsys, ["validate", "pendulum", "--out", str(target)])
    line = _one_line(capsys, ["validate", "pendulum", "--out", str(target / "sub")])
    assert f"{target} is a file, so the folder {target / 'sub'} cannot be made" in line


def test_out_that_cannot_be_written_is_refused_before_the_run(tmp_path, monkeypatch, capsys):
    """A read-only mount, simulated where the test runs as root (permissions do not stop root)."""
    import tempfile

    _tripwire(monkeypatch)

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    line = _one_line(capsys, ["run", "pendulum", "--out", str(tmp_path / "new" / "out")])
    assert line == f"mslab: error: --out: cannot write in {tmp_path} (Read-only file system)"
    assert not (tmp_path / "new").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_out_in_a_read_only_folder_is_refused(tmp_path, monkeypatch, capsys):
    _tripwire(monkeypatch)
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        line = _one_line(capsys, ["run", "pendulum", "--out", str(locked / "out")])
        assert f"cannot write in {locked}" in line
    finally:
        locked.chmod(0o755)


def test_out_without_room_for_the_announced_size_is_refused(tmp_path, monkeypatch, capsys):
    import shutil

    _tripwire(monkeypatch)
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=10_000))
    line = _one_line(capsys, ["run", "pendulum", "--out", str(tmp_path / "out")])
    # pendulum: 401 samples of 2 particles in 2D = 401 * (2*2*2 + 5) * 8 bytes, plus 1 MB for figures
    need = (401 * 13 * 8 + 2**20) / 2**20
    assert f"only 0.00954 MB free on the file system of {tmp_path}; the outputs need about {need:.3g} MB" \
        in line


def test_a_full_disk_names_the_file(tmp_path):
    from mslab.files import atomic_write

    def full(tmp: str) -> None:
        Path(tmp).write_text("x")
        raise OSError(errno.ENOSPC, "No space left on device")

    target = tmp_path / "run.npz"
    with pytest.raises(OSError, match=f"{target}: no space left on the device while writing it"):
        atomic_write(target, full)
    assert list(tmp_path.iterdir()) == []


# -- messages -----------------------------------------------------------------------------------------
def test_method_suggestions_are_sensible(capsys):
    line = _one_line(capsys, ["run", "pendulum", "--method", "rk5"])
    assert "unknown method 'rk5' (close: rk3, rk4, rk6)" in line
    line = _one_line(capsys, ["run", "pendulum", "--method", "rk44"])
    assert "(did you mean 'rk4'?)" in line


def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out.strip() == f"mslab {mslab.__version__}"


def test_validate_takes_the_run_settings_its_refusal_advises(capsys):
    line = _one_line(capsys, ["validate", "chain", "--max-memory", "1k", "--no-timing"])
    advice = line.split("use save_every >= ")[1].split()[0]
    assert main(["validate", "chain", "--max-memory", "1k", "--no-timing", "--save-every", advice]) == 0
    assert f"(save_every {advice})" in capsys.readouterr().out
    line = _one_line(capsys, ["validate", "chain", "--no-timing", "--dt", "0.003"])
    assert "run.dt" in line
    assert main(["validate", "chain", "--no-timing", "--method", "rk4", "--t-end", "0.5", "--json"]) == 0
    assert '"method": "rk4"' in capsys.readouterr().out


def test_drift_verdict_bounded_growing_or_damped():
    from mslab.commands.run import drift_words

    t = np.linspace(0.0, 10.0, 401)
    assert "bounded" in drift_words(3.6e-5 * np.sin(7 * t) ** 2, "verlet")
    assert "adds energy" not in drift_words(3.6e-5 * np.sin(7 * t) ** 2, "verlet")
    assert drift_words(1e-3 * t, "euler") == " (the ledger gained energy: euler adds energy)"
    assert drift_words(-1e-3 * t, "implicit_euler") == \
        " (the ledger lost energy: numerical damping of implicit_euler)"
    assert drift_words(1e-9 * t, "rk4") == ""
    # a one-sided loss that levels off (implicit Euler on a cloth coming to rest) is damping
    assert "numerical damping" in drift_words(-0.6 * (1 - np.exp(-5 * t)), "implicit_euler")
    run = mslab.simulate(mslab.load_scene("pendulum", method="verlet"))
    drift = run.energy.relative_drift()
    assert drift[-1] > 1e-6  # the case of the issue: a small positive final drift, bounded all along
    assert "bounded" in drift_words(drift, "verlet")


def test_pinned_scene_stays_still_for_every_method():
    b = mslab.SceneBuilder(dim=2)
    p = b.add_particle([0.0, 0.0], mass=1.0, pinned=True)
    q = b.add_particle([1.0, 0.0], mass=1.0, pinned=True)
    b.add_spring(p, q, stiffness=100.0, rest_length=0.5)
    b.add_gravity([0.0, -9.81])
    scene = b.build()
    for method in mslab.methods():
        traj = mslab.simulate(scene, method=method, dt=1e-2, t_end=0.1, backend="numpy")
        np.testing.assert_array_equal(traj.x, np.broadcast_to(scene.state0.x, traj.x.shape))
        np.testing.assert_array_equal(traj.v, 0.0)


# -- issue 37: the red team's tracebacks, now one line and exit 2 -------------------------------------

def test_a_string_dim_is_one_line(tmp_path, capsys):
    path = _write(tmp_path, "dim.toml", PENDULUM.replace("dim = 2", 'dim = "2"'))
    assert "scene.dim" in _one_line(capsys, ["validate", str(path)])


@pytest.mark.parametrize("header", ["[" + ".".join(["a"] * 2000) + "]\nx = 1\n",
                                    ".".join(["b"] * 2000) + " = 1\n"])
def test_keys_nested_thousands_deep_by_dots_are_one_line(tmp_path, capsys, header):
    path = _write(tmp_path, "deep.toml", header + PENDULUM)
    assert "nested more than" in _one_line(capsys, ["validate", str(path)])


@pytest.mark.parametrize("argv", [["validate", "pendulum", "--max-memory", "1e999"],
                                  ["precision", "pendulum", "--rtols", "-1"],
                                  ["precision", "pendulum", "--rtols", "nan"],
                                  ["precision", "pendulum", "--budget", "nan"]])
def test_odd_numbers_on_the_command_line_are_one_line(capsys, argv):
    _one_line(capsys, argv)


def test_validate_warns_for_a_dt_over_the_stable_limit_like_run(capsys):
    """rk4 on the pendulum: limit 2.8/omega; dt 5x over it is warned about (one line), still exit 0."""
    argv = ["validate", "pendulum", "--method", "rk4", "--t-end", "1", "--no-timing", "--dt"]
    assert main([*argv, "0.1"]) == 0
    err = capsys.readouterr().err
    assert err.count("mslab: warning:") == 1 and "is above it" in err
    assert main([*argv, "0.001"]) == 0
    assert "warning" not in capsys.readouterr().err
