"""Ctrl-C in `mslab compare` keeps the methods already finished (issue 39): with `--out` they are
written, the message says which were kept, the exit code is 130. Before, everything was discarded."""

from __future__ import annotations

import importlib
import json

from mslab.cli import main

SIMULATE = importlib.import_module("mslab.simulate")  # the module (mslab.simulate is the function)


def test_ctrl_c_in_compare_keeps_and_writes_the_finished_methods(tmp_path, monkeypatch, capsys):
    real = SIMULATE.simulate
    runs = []

    def interrupted_third(scene, method, *args, **kwargs):  # Ctrl-C during the third method's run
        runs.append(method)
        if method == "rk4":
            raise KeyboardInterrupt
        return real(scene, method, *args, **kwargs)

    monkeypatch.setattr(SIMULATE, "simulate", interrupted_third)
    code = main(["compare", "pendulum", "--methods", "euler", "symplectic_euler", "rk4", "verlet",
                 "--t-end", "0.5", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 130
    assert "interrupted after 2 of 4 methods (kept: euler, symplectic_euler)" in err
    doc = json.loads((tmp_path / "compare.json").read_text())
    assert [m["method"] for m in doc["methods"]] == ["euler", "symplectic_euler"]
    assert "verlet" not in runs  # nothing ran after the interrupt
