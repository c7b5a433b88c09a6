"""Ctrl-C in `mslab precision` keeps the methods already finished (issue 39): with `--out` they are
written, the message names them, the exit code is 130. Before, everything computed was discarded.

The interrupt is a real SIGINT through the command line's handler, sent by the process to itself
when the sweep starts the third method's first run: no timing decides where it lands.
"""

from __future__ import annotations

import json
import os
import signal

import numpy as np

import mslab.precision.runs as runs
from mslab.cli import main

ARGS = ["precision", "oscillator", "--methods", "euler", "heun", "rk4", "verlet", "--dts", "0.01", "0.005",
        "--t-end", "0.5", "--scipy", "--repeats", "1", "--budget", "0.05"]


def test_ctrl_c_in_precision_keeps_and_writes_the_finished_methods(tmp_path, monkeypatch, capsys):
    real = runs._call
    started = []

    def interrupted_at_rk4(task):
        started.append(task[2])
        if task[2] == "rk4":
            os.kill(os.getpid(), signal.SIGINT)  # the CLI's handler raises KeyboardInterrupt here
            raise AssertionError("the SIGINT did not interrupt the sweep")
        return real(task)

    assert main([*ARGS, "--json"]) == 0  # the same sweep, not interrupted
    whole = {(r["method"], r["dt"]): r for r in json.loads(capsys.readouterr().out)["records"]}
    monkeypatch.setattr(runs, "_call", interrupted_at_rk4)
    code = main([*ARGS, "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == 130
    line = f"mslab: interrupted after 2 of 4 methods (kept: euler, heun); written to {tmp_path}"
    assert err.splitlines() == [line]
    assert "verlet" not in started and started.count("rk4") == 1  # nothing ran after the interrupt
    doc = json.loads((tmp_path / "precision.json").read_text())
    assert [(r["method"], r["dt"]) for r in doc["records"]] == [(m, dt) for m in ("euler", "heun")
                                                                for dt in (0.01, 0.005)]
    for r in doc["records"]:  # each kept record is the uninterrupted sweep's, timed
        assert r["error"] == whole[r["method"], r["dt"]]["error"] and r["n_force"] > 0
        assert np.isfinite(r["wall_time"]) and r["wall_time"] > 0
    assert set(doc["expected_orders"]) == {"euler", "heun"}
    assert {p.name for p in tmp_path.iterdir()} >= {"precision.json", "convergence.png"}
    assert "euler" in out and "rk4" not in out
