"""The lessons' tools: ``tools/lesson_times.py`` (each lesson's CPU time) and the stored long runs.

lesson_times is checked on tiny notebooks for what it prints and its exit codes, never for a
time (no timing assertion: any run takes some CPU, so ``--limit 0`` flags it). The stored long
runs of lesson 03 (``lessons/03_long_runs.json``) must be what ``tools/lesson03_long_runs.py``
computes today, so a library change that moves them shows here, not as a silently stale lesson.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import nbformat
import pytest

TOOLS = Path(__file__).resolve().parents[1] / "tools"


def _tool(name: str):
    sys.path.insert(0, str(TOOLS))
    spec = importlib.util.spec_from_file_location(name, TOOLS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _notebook(path: Path, source: str) -> Path:
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(source)])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nbformat.write(nb, path)
    return path


def test_lesson_times_prints_each_notebook_and_flags_over_limit(tmp_path: Path, capsys) -> None:
    times = _tool("lesson_times")
    a, b = _notebook(tmp_path / "01_a.ipynb", "print(1)"), _notebook(tmp_path / "02_b.ipynb", "x = 2")
    assert times.main([str(a), str(b)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == ["01_a.ipynb", "02_b.ipynb"]
    assert all("CPU" in line and "wall" in line and line.endswith("(cold)") for line in lines)
    assert times.main([str(a), "--warm", "--limit", "0"]) == 1
    assert capsys.readouterr().out.rstrip().endswith("(warm)  OVER")


def test_lesson_times_reports_a_failing_notebook(tmp_path: Path, capsys) -> None:
    times = _tool("lesson_times")
    bad = _notebook(tmp_path / "03_bad.ipynb", "raise ValueError('planted')")
    assert times.main([str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"lesson_times: error: {bad}")


@pytest.mark.slow
def test_lesson03_long_runs_reproduce_the_stored_file(capsys) -> None:
    assert _tool("lesson03_long_runs").main(["--check"]) == 0, capsys.readouterr().out
