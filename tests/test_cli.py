"""The ``mslab`` command: scenes, run, validate. Mistakes end as one line naming file and key (exit 2);
--json is one parseable document; data files appear complete or not at all."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import mslab
from mslab.cli import main
from mslab.scenes.loader import scene_path
from tests.scene_cases import BAD, bad_file

ROOT = Path(__file__).resolve().parents[1]


def mslab_cmd(*args, cwd=None, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mslab", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=900, env={**os.environ, "PYTHONPATH": str(ROOT)}, **kwargs)


@pytest.mark.parametrize("command", ["run", "validate"])
@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_one_line_exit_2(tmp_path, capsys, case, command):
    path, key, reason = bad_file(tmp_path, case)
    assert main([command, str(path)]) == 2
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"mslab: error: {path}: {key}: ")
    assert reason in lines[0]
    assert out == ""


def test_bad_scenes_through_subprocess(tmp_path):
    """The real command in a subprocess: every bad file gives one line naming file and key; exit 2."""
    cases = sorted(BAD)
    files = [bad_file(tmp_path, case) for case in cases]
    proc = mslab_cmd("validate", *[f for f, _, _ in files])
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == len(files), proc.stderr
    for line, (path, key, reason) in zip(lines, files, strict=True):
        assert line.startswith(f"mslab: error: {path}: {key}: ") and reason in line
    assert "Traceback" not in proc.stderr
    for case in ("syntax", "unknown_key"):
        path, key, _ = bad_file(tmp_path, case)
        proc = mslab_cmd("run", path)
        assert proc.returncode == 2
        assert proc.stdout == ""
        assert proc.stderr.splitlines() == [proc.stderr.strip()]
        assert proc.stderr.startswith(f"mslab: error: {path}: {key}: ")


def test_bad_options_exit_2(capsys):
    assert main(["run", "chain", "--method", "rk5"]) == 2
    assert main(["run", "chain", "--dt", "-1"]) == 2
    assert main(["run", "no_such_scene"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3 and all(line.startswith("mslab: error: ") for line in err)
    assert "run.method" in err[0] and "valid methods" in err[0]
    assert "--dt: must be > 0, got -1.0" in err[1]
    assert "built-in scenes" in err[2]


def test_run_json_animate(tmp_path):
    out = tmp_path / "out"
    proc = mslab_cmd("run", "chain", "--t-end", "0.05", "--json", "--animate", "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""  # no progress bar when stderr is not a terminal
    doc = json.loads(proc.stdout)
    stats = doc["stats"]
    method = mslab.get_method(doc["method"])
    assert stats["steps"] == 50
    assert stats["n_force"] == 50 * method.n_stages + method.n_start
    assert doc["complete"] is True
    assert set(doc["files"]) == {"data", "energy_figure", "final_figure", "animation"}
    data = np.load(doc["files"]["data"])
    assert bool(data["complete"]) and data["x"].shape == (6, 10, 2)  # save_every 10: t = 0, 0.01, ..., 0.05
    np.testing.assert_allclose(data["t"], np.linspace(0.0, 0.05, 6))
    total = data["kinetic"] + data["potential"] + data["dissipated"]
    assert doc["energy"]["final_total"] == pytest.approx(total[-1])
    with Image.open(doc["files"]["animation"]) as gif:
        assert gif.n_frames == 6
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_instability_one_line_exit_3(tmp_path, capsys):
    code = main(["run", "stiff_chain", "--method", "euler", "--t-end", "1", "--out", str(tmp_path)])
    assert code == 3
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("mslab: error:")]
    assert len(errors) == 1 and "blew up" in errors[0]
    data = np.load(tmp_path / "stiff_chain.npz")  # the part computed before the blow-up
    assert not bool(data["complete"]) and np.all(np.isfinite(data["x"]))


def _interrupt_check(proc_returncode: int, err: str, out: Path, t_end: float) -> list[str]:
    """Exit 130, one line saying so, no traceback; the folder holds complete files or nothing.

    Returns the names of the files written (complete by the atomic-write rule).
    """
    lines = err.splitlines()
    assert proc_returncode == 130, err
    assert all(line.startswith("mslab: ") for line in lines), err  # no traceback, no "Exception ignored"
    assert [line for line in lines if line.startswith("mslab: interrupted")] == [lines[-1]], err
    names = sorted(p.name for p in out.iterdir()) if out.exists() else []
    assert not [n for n in names if n.startswith(".")], f"temporary files left behind: {names}"
    npz = out / "chain.npz"
    if npz.exists():
        with np.load(npz) as data:
            assert data["x"].shape == (len(data["t"]), 10, 2) and np.all(np.isfinite(data["x"]))
            assert bool(data["complete"]) == (data["t"][-1] == t_end)
    return names


def _without_ignored_sigint() -> None:
    """In the child: Ctrl-C as at a terminal (a test runner may have told its workers to ignore it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


#: (phase the process interrupts itself in, fresh compiled-code cache, files expected afterwards)
PHASES = [
    ("import", False, []),
    ("loading numba", True, []),
    ("compiling", True, []),  # a fresh cache: numba compiles
    ("compiling", False, []),  # this session's cache: numba loads the loops (or compiles them)
    ("stepping", False, ["chain.npz", "chain_energy.png", "chain_final.png"]),
    ("saving", False, ["chain.npz"]),
]


@pytest.mark.parametrize(("phase", "cold", "files"), PHASES,
                         ids=[f"{p}-{'cold' if c else 'cache'}" for p, c, _ in PHASES])
def test_ctrl_c_in_every_phase_ends_with_130_and_one_line(tmp_path, phase, cold, files):
    """A Ctrl-C in each phase of ``mslab run``: exit 130, one line, a complete partial save or nothing.

    The process sends itself SIGINT on entering the phase (``MSLAB_TEST_INTERRUPT``,
    :func:`mslab.interrupts.phase`): no timing decides where it lands.
    """
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MSLAB_TEST_INTERRUPT": phase, "MSLAB_BACKEND": "numba"}
    if cold:
        env["MSLAB_CACHE_DIR"] = env["NUMBA_CACHE_DIR"] = str(tmp_path / "cache")
    proc = subprocess.run([sys.executable, "-m", "mslab", "run", "chain", "--method", "rk4", "--t-end", "20",
                           "--save-every", "1000", "--out", str(out)], capture_output=True, text=True,
                          env=env, timeout=900, preexec_fn=_without_ignored_sigint)
    assert _interrupt_check(proc.returncode, proc.stderr, out, 20.0) == files
    last = proc.stderr.splitlines()[-1]
    if phase in ("loading numba", "compiling"):
        assert last.startswith(f"mslab: interrupted while {phase}"), last
    if phase == "stepping":
        assert "mslab: interrupted at t = " in last and "saved" in last
    if phase == "saving":
        assert last == f"mslab: interrupted while writing the outputs; complete files: {out / 'chain.npz'}"


def test_ctrl_c_in_a_program_is_held_until_the_compilation_is_through():
    """In a program (Python's own handler), a Ctrl-C during protected work is raised after it, not inside."""
    from mslab import interrupts

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a plain program
    done = []
    try:
        with pytest.raises(KeyboardInterrupt):
            with interrupts.protected("compiling a test"):
                os.kill(os.getpid(), signal.SIGINT)
                done.extend(range(3))  # the section runs to its end
    finally:
        signal.signal(signal.SIGINT, previous)
    assert done == [0, 1, 2]
    assert signal.getsignal(signal.SIGINT) is previous


def test_ctrl_c_from_outside_ends_with_130_and_one_line(tmp_path):
    """A real SIGINT from another process, sent once the run announces itself: whatever it interrupts
    (the stability analysis, compiling or loading, stepping, saving), exit 130 and one line."""
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "mslab", "run", "chain", "--method", "rk4",
                             "--t-end", "20", "--save-every", "1000", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT), "MSLAB_BACKEND": "numba"},
                            preexec_fn=_without_ignored_sigint)
    try:
        for line in proc.stdout:  # readiness: the scene is loaded and the command's handler installed
            if line.startswith("chain: "):
                break
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=900)  # a guard against a hang, not a timing
    finally:
        if proc.poll() is None:
            proc.kill()
    _interrupt_check(proc.returncode, err, out, 20.0)


def test_scenes_and_validate_commands(capsys):
    assert main(["scenes", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [s["name"] for s in doc["scenes"]] == mslab.scene_names()
    assert main(["scenes", "pendulum"]) == 0
    assert capsys.readouterr().out == scene_path("pendulum").read_text()
    assert main(["validate", "chain", str(scene_path("cloth"))]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and all(": ok (" in line for line in lines)


def test_an_unwritable_output_is_one_line_naming_the_file(tmp_path, capsys, monkeypatch):
    """An OSError from the system (here: a folder where the CSV goes) reads FILE: reason, no errno."""
    import mslab.cli as cli

    def refuse(args):
        raise PermissionError(13, "Permission denied", str(tmp_path / "book.csv.journal"))

    parser = cli.build_parser()
    args = parser.parse_args(["validate", "x.toml"])
    monkeypatch.setattr(cli, "build_parser", lambda: type("P", (), {"parse_args": lambda self, a: args})())
    args.func = refuse
    assert cli.main(["validate", "x.toml"]) == 2
    assert capsys.readouterr().err.splitlines() == [f"mslab: error: {tmp_path / 'book.csv.journal'}: "
                                                    "permission denied"]
