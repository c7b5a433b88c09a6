"""Issue 11, "what a newcomer trips over": one test per defect, each reproducing it first.

Runs that announce their cost and refuse what cannot fit in memory, cheap checks before
expensive ones, feedback by the clock, timings without compilation, files others can read.
"""

from __future__ import annotations

import importlib
import io
import json
import os
import signal
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mslab
from mslab.cli import main
from mslab.commands.common import atomic_write
from mslab.scenes.loader import scene_path
from tests.scene_cases import BAD_OPTIONS, BAD_RUN, bad_run_file

ROOT = Path(__file__).resolve().parents[1]


# -- defect 4: files written with the umask's permissions --------------------------------------------
def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_atomic_write_gives_the_umask_mode_not_0600(tmp_path):
    old = os.umask(0o022)
    try:
        plain = tmp_path / "plain.txt"
        plain.write_text("x")  # what an ordinary open() gives: the reference
        written = atomic_write(tmp_path / "data.npz", lambda tmp: np.savez(tmp, a=np.zeros(3)))
        assert _mode(written) == _mode(plain) == 0o644
        os.umask(0o077)
        private = atomic_write(tmp_path / "private.txt", lambda tmp: Path(tmp).write_text("y"))
        assert _mode(private) == 0o600
    finally:
        os.umask(old)


def test_atomic_write_keeps_an_existing_files_mode(tmp_path):
    path = tmp_path / "table.csv"
    path.write_text("old")
    path.chmod(0o640)
    atomic_write(path, lambda tmp: Path(tmp).write_text("new"))
    assert path.read_text() == "new" and _mode(path) == 0o640


# -- helpers -----------------------------------------------------------------------------------------
def mslab_cmd(*args, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mslab", *map(str, args)], capture_output=True, text=True,
                          timeout=900, env={**os.environ, "PYTHONPATH": str(ROOT)}, **kwargs)


def no_run(monkeypatch):
    """Make any simulate call fail the test: a refused run must not compute anything."""
    module = importlib.import_module("mslab.simulate")  # the module, not the function mslab.simulate

    def forbidden(*args, **kwargs):
        raise AssertionError("simulate was called")

    monkeypatch.setattr(module, "simulate", forbidden)


def cloth_file(tmp_path, n: int, method: str, dt: float = 1e-3, t_end: float = 2e-3) -> Path:
    text = scene_path("cloth").read_text()
    for old, new in (("nx = 10", f"nx = {n}"), ("ny = 10", f"ny = {n}"),
                     ('method = "implicit_euler"', f'method = "{method}"'), ("dt = 0.02", f"dt = {dt}"),
                     ("t_end = 2.0", f"t_end = {t_end}")):
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / f"cloth{n}.toml"
    path.write_text(text)
    return path


# -- defect 1: no eigenvalue analysis where it changes nothing; Ctrl-C before the run ------------------
def test_a_stable_method_skips_the_eigenvalue_analysis(monkeypatch, capsys):
    import mslab.stability

    def forbidden(*args, **kwargs):
        raise AssertionError("eigenvalues computed for an A-stable method")

    monkeypatch.setattr(mslab.stability, "eigenvalues", forbidden)
    assert main(["run", "cloth", "--t-end", "0.04"]) == 0
    out = capsys.readouterr().out
    assert "no limit (implicit_euler is A-stable; eigenvalue analysis skipped)" in out


def test_a_large_scene_skips_the_prediction_with_a_note(tmp_path, monkeypatch, capsys):
    import mslab.stability

    monkeypatch.setattr(mslab.stability, "eigenvalues", lambda *a, **k: pytest.fail("eigenvalues computed"))
    path = cloth_file(tmp_path, 41, "rk4", dt=1e-4, t_end=2e-4)  # 41 x 41 x 3 = 5043 unknowns > 5000
    assert main(["run", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["predicted_stable_dt"] is None
    assert any("prediction skipped: 5043 unknowns, more than 5000" in n for n in doc["notes"])


def test_ctrl_c_during_the_prediction_writes_nothing(tmp_path, monkeypatch, capsys):
    import mslab.stability

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(mslab.stability, "predicted_stable_dt", interrupted)
    out = tmp_path / "out"
    assert main(["run", "stiff_chain", "--method", "rk4", "--out", str(out)]) == 130
    err = capsys.readouterr().err.splitlines()
    assert err == ["mslab: interrupted before the run started: nothing computed, nothing written"]
    assert not out.exists()  # no empty output folder


# -- defect 2 and build item 1: the cost before the run, refused over the memory budget --------------
@pytest.mark.parametrize("command", ["run", "validate"])
@pytest.mark.parametrize("case", sorted(BAD_RUN))
def test_a_run_that_cannot_fit_is_refused_before_computing(tmp_path, monkeypatch, capsys, case, command):
    no_run(monkeypatch)
    path, key, reason = bad_run_file(tmp_path, case)
    assert main([command, str(path)]) == 2
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"mslab: error: {path}: {key}: ") and reason in lines[0]
    assert "or t_end <=" in lines[0]
    assert out == ""


@pytest.mark.parametrize("case", sorted(BAD_OPTIONS))
def test_option_mistakes_one_line_exit_2_nothing_run(tmp_path, monkeypatch, capsys, case):
    no_run(monkeypatch)
    extra, key, reason = BAD_OPTIONS[case]
    assert main(["run", "chain", *extra, "--out", str(tmp_path / "out")]) == 2
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("mslab: error: ") and reason in lines[0], err
    assert f"{key}: " in lines[0]
    assert out == "" and not (tmp_path / "out").exists()


def test_memory_figures_and_the_suggested_fix_fit():
    """The refusal's numbers: bytes = samples x (2 n dim + 5) x 8; the suggested save_every fits."""
    from mslab.budget import memory_problem, run_cost

    scene = mslab.load_scene("chain", dt=1e-4, t_end=100.0, save_every=1)
    cost = run_cost(scene)
    assert (cost.steps, cost.n_saved) == (10**6, 10**6 + 1)
    assert cost.bytes_saved == (10**6 + 1) * (2 * 10 * 2 + 5) * 8
    budget = 10**6
    line = memory_problem(cost, budget)
    every = int(line.split("save_every >= ")[1].split()[0])
    assert memory_problem(run_cost(scene, save_every=every), budget) is None
    assert memory_problem(run_cost(scene, save_every=every - 1), budget) is not None
    t_end = float(line.split("t_end <= ")[1].split()[0])
    assert memory_problem(run_cost(scene, t_end=t_end), budget) is None


def test_run_announces_its_cost_and_validate_the_same(capsys):
    assert main(["run", "hanging_rope"]) == 0
    out = capsys.readouterr().out
    assert "cost: 3000 steps, 151 saved samples (save_every 20): " in out
    assert main(["validate", "hanging_rope"]) == 0
    line = capsys.readouterr().out
    assert "3000 steps, 151 saved samples (save_every 20): " in line and "(from a few timed steps)" in line


def test_validate_time_estimate_is_the_per_step_cost_times_the_steps(monkeypatch, capsys):
    """The estimate from a few timed steps leaves the start-up cost out and scales the step cost.

    On a clock where a run of n steps takes 10 ms + n x 1 ms (no real time involved), the
    estimate is exactly 1 ms x the run's steps.
    """
    import types

    import mslab.budget

    clock = FakeClock()
    runs = []

    def timed_run(scene, method, dt, t_end, save_every, **options):
        n = round(t_end / dt)
        runs.append(n)
        clock.now += 0.010 + n * 1e-3

    monkeypatch.setattr(importlib.import_module("mslab.simulate"), "simulate", timed_run)
    monkeypatch.setattr(mslab.budget, "time", types.SimpleNamespace(perf_counter=clock))
    assert main(["validate", "cloth", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)["files"][0]
    assert runs[:3] == [1, 1, 2] and len(runs) > 3  # a warm-up step, then 1, 2, 4, ... steps
    assert record["seconds_per_step"] == pytest.approx(1e-3, rel=1e-9)
    assert record["estimated_seconds"] == pytest.approx(1e-3 * record["steps"], rel=1e-9)


# -- defect 3: tools checked before the run --------------------------------------------------------------
def test_missing_ffmpeg_is_refused_before_the_run(tmp_path, monkeypatch, capsys):
    from matplotlib import animation

    no_run(monkeypatch)
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    assert main(["run", "chain", "--animate", "mp4", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == ["mslab: error: --animate: ffmpeg not found; install it or use --animate gif"]
    assert not (tmp_path / "o").exists()


# -- defect 4 at the command line: figures and data readable by others -----------------------------------
def test_run_outputs_follow_the_umask(tmp_path):
    command = f"umask 022 && {sys.executable} -m mslab run chain --t-end 0.05 --out {tmp_path}/o"
    proc = subprocess.run(command, shell=True, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 0, proc.stderr
    files = list((tmp_path / "o").iterdir())
    assert len(files) == 3 and all(_mode(f) == 0o644 for f in files)
    assert _mode(tmp_path / "o") == 0o755


# -- defect 5: a failed fixed-point iteration is not "drifting (blew up)" -----------------------------------
def test_compare_shows_a_convergence_error_as_what_it_is(capsys):
    assert main(["compare", "stiff_chain", "--methods", "implicit_euler_fp", "euler", "--t-end", "1"]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("implicit_euler_fp"))
    assert "no convergence at step 1 (t = 0.01)" in row and "blew up" not in row
    assert row.split()[1] == "1"  # the failing step, counted with its work
    assert "fixed-point iteration did not converge" in out
    euler = next(line for line in out.splitlines() if line.startswith("euler "))
    assert "drifting: blew up at step" in euler


# -- defect 6: one stopping point for steps, time and work -------------------------------------------------
def test_energy_blow_up_steps_time_and_work_agree(capsys):
    assert main(["run", "pendulum", "--method", "euler", "--t-end", "40", "--json"]) == 3
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    stats, stop = doc["stats"], doc["stopped_at"]
    step = int(captured.err.split("blew up by step ")[1].split()[0])
    assert stats["steps"] == stop["step"] == step < 40000
    assert stats["n_force"] == step  # forward Euler: one force evaluation per step
    assert stop["t"] == pytest.approx(step * 1e-3)
    assert doc["t_end"] == 40.0  # the requested end time, not rewritten
    assert doc["t_last_saved"] < stop["t"] and doc["complete"] is False
    assert main(["run", "pendulum", "--method", "euler", "--t-end", "40"]) == 3
    out = capsys.readouterr().out
    assert f"stopped at step {step} of 40000 (t = {step * 1e-3:.6g} s of 40 s)" in out
    assert f"(to step {step})" in out


# -- defect 7 and build item 4: compilation out of the timing columns ----------------------------------------
def test_demo_times_each_method_after_a_warm_up(tmp_path, monkeypatch, capsys):
    from mslab import demo

    calls = []
    real = mslab.simulate

    def spy(scene, method, *args, **kwargs):
        calls.append((method, kwargs.get("t_end")))
        return real(scene, method, *args, **kwargs)

    monkeypatch.setattr(demo.mslab, "simulate", spy)
    demo.chain_tour(tmp_path, dt=1e-3, t_end=0.1)
    for method in mslab.COURSE_METHODS:
        mine = [t for m, t in calls if m == method]
        assert mine[0] == pytest.approx(0.01) and mine[1] == 0.1  # warm-up first, then the timed run
    out = capsys.readouterr().out
    assert "compile [s]" in out and "numba compilation" in out


# -- defect 12: validate takes --out; --json is quiet on stderr ---------------------------------------------
def test_validate_out_and_json_quiet(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[scene]\ndim = = 2\n")
    proc = mslab_cmd("validate", "chain", bad, "--json", "--no-timing", "--out", tmp_path / "v")
    assert proc.returncode == 2 and proc.stderr == ""
    doc = json.loads(proc.stdout)
    assert [f["ok"] for f in doc["files"]] == [True, False]
    assert json.loads((tmp_path / "v" / "validate.json").read_text()) == doc


# -- defect 13 and build item 3: feedback by the clock ------------------------------------------------------
class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class FakeClock:
    """A clock that moves only when told (no test waits on the real one)."""

    def __init__(self):
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_progress_appears_by_the_clock_whatever_the_step_count():
    from mslab.integrators.base import Integrator
    from mslab.progress import Progress

    clock = FakeClock()
    ticks = []

    class Slow(Integrator):  # three slow steps: never enough for a step-count rule
        name, order = "slow_euler", 1

        def step(self, system, state, dt):
            clock.now += 0.25  # a step of 0.25 s on the bar's clock
            bar.tick()  # what the bar's thread does every 0.2 s
            ticks.append(tty.getvalue())
            return state

    scene = mslab.load_scene("pendulum")
    tty = FakeTerminal()
    bar = Progress(3, "slow_euler", stream=tty, delay=0.3, interval=3600, clock=clock)
    mslab.simulate(scene, Slow(), dt=0.1, t_end=0.3, progress=bar, check_stability=False)
    bar.close()
    assert ticks[0] == ""  # 0.25 s: before the delay
    assert "slow_euler: [" in ticks[1] and "/3 steps" in ticks[1]  # 0.5 s: drawn, during the run
    quick = FakeTerminal()
    with Progress(3, "x", stream=quick, delay=0.3, interval=3600, clock=clock) as fast:
        clock.now += 0.29
        fast.update(3)
        fast.tick()
    assert quick.getvalue() == ""  # work done within the delay: nothing drawn
    pipe = io.StringIO()
    with Progress(3, "x", stream=pipe, delay=0.0, interval=3600, clock=clock) as piped:
        clock.now += 10.0
        piped.tick()
    assert pipe.getvalue() == ""  # not a terminal: nothing


def test_compare_names_the_current_method_on_its_bar():
    from mslab.precision import energy_drift

    class Spy:
        n = 0
        names: list = []

        def update(self, n=1):
            self.n += n

        def describe(self, desc, total=None):
            self.names.append(desc)

    spy = Spy()
    energy_drift(mslab.load_scene("chain"), ["rk4", "verlet"], t_end=0.1, progress=spy, warm_up=False)
    assert spy.names == ["rk4 (1/2)", "verlet (2/2)"] and spy.n == 2 * 100


def test_animation_reports_each_frame(tmp_path):
    from mslab.plots import animate

    scene = mslab.load_scene("chain")
    traj = mslab.simulate(scene, t_end=0.05)
    seen = []

    class Spy:
        def update(self, n=1):
            seen.append(n)

        def describe(self, desc, total=None):
            seen.append((desc, total))

    animate(traj, scene, tmp_path / "a.gif", progress=Spy())
    assert seen[0] == ("writing gif", 6) and seen[1:] == [1] * 6


def test_stability_warning_is_printed_before_the_run_ends():
    """heun on the undamped pendulum warns; the line arrives before the run has finished its steps.

    The run interrupts itself at its first progress report (``MSLAB_TEST_INTERRUPT=stepping``),
    so it never finishes: a warning kept until the end of the run would not be printed before
    the interruption's line. No timing involved.
    """
    proc = subprocess.run([sys.executable, "-m", "mslab", "run", "pendulum", "--method", "heun",
                           "--t-end", "5000", "--save-every", "10000"], stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True, timeout=900,
                          env={**os.environ, "PYTHONPATH": str(ROOT), "MSLAB_TEST_INTERRUPT": "stepping"},
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines = proc.stderr.splitlines()
    assert proc.returncode == 130, proc.stderr
    assert lines[0].startswith("mslab: warning: heun has no stable dt on this scene"), proc.stderr
    assert lines[-1].startswith("mslab: interrupted at t = ")


# -- defect 14: messages that say what they mean -----------------------------------------------------------
def test_messages_say_what_they_mean(capsys):
    from mslab.commands.run import drift_words, prediction_line

    assert main(["run", "cloth", "--t-end", "0.4"]) == 0
    out = capsys.readouterr().out
    assert "(the ledger lost energy: numerical damping of implicit_euler)" in out
    line = prediction_line("heun", 1e-3, 0.0)
    assert "= 0" not in line and "grow" in line and "slowly when dt is small" in line
    assert drift_words(3e-3, "euler") == " (the ledger gained energy: euler adds energy)"
    assert drift_words(1e-9, "rk4") == ""


# -- build item 6: mslab methods --------------------------------------------------------------------------
def test_methods_command_lists_order_stages_family(capsys):
    assert main(["methods", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["methods"]
    assert [r["method"] for r in rows] == mslab.methods()
    rk4 = next(r for r in rows if r["method"] == "rk4")
    assert (rk4["order"], rk4["stages"], rk4["explicit"]) == (4, 4, True)
    for r in rows:
        m = mslab.get_method(r["method"])
        assert r["family"] == getattr(m, "family", type(m).__name__)
    assert main(["methods"]) == 0
    assert capsys.readouterr().out.splitlines()[0].split() == ["method", "order", "stages", "family",
                                                             "explicit", "symplectic", "course"]
