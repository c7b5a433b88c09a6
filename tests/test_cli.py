"""The ``mslab`` command: scenes, run, validate. Mistakes end as one line naming file and key (exit 2);
--json is one parseable document; data files appear complete or not at all."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
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
                          cwd=cwd, timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)}, **kwargs)


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
    assert "run.dt" in err[1]
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


def test_interrupted_run_saves_whole_file_or_nothing(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "mslab", "run", "hanging_rope", "--t-end", "2000",
                             "--save-every", "1000", "--method", "rk4", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        for line in proc.stdout:
            if line.startswith("running"):
                break
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    # interrupted before the run started (e.g. while compiling): no folder at all
    assert not out.exists() or not [p for p in out.iterdir() if p.name.startswith(".")], \
        "temporary files left behind"
    npz = out / "hanging_rope.npz"
    if npz.exists():
        data = np.load(npz)
        assert not bool(data["complete"])
        assert 0 <= data["t"][-1] < 2000 and data["x"].shape == (len(data["t"]), 20, 2)
        assert "saved" in err


def test_scenes_and_validate_commands(capsys):
    assert main(["scenes", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [s["name"] for s in doc["scenes"]] == mslab.scene_names()
    assert main(["scenes", "pendulum"]) == 0
    assert capsys.readouterr().out == scene_path("pendulum").read_text()
    assert main(["validate", "chain", str(scene_path("cloth"))]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and all(": ok (" in line for line in lines)
