"""Trivial answers score what the untouched release scores: nothing; the reference scores everything.

Zeros, "identity" steps that return their input, and functions that raise RuntimeError
are graded for every exercise, next to a classmate with the reference solutions who must
keep full marks (issue 10: weak tests accepted 14/98 of such answers). The same grading
(``mslab grade --json --csv``, one class of five over the twelve exercises) checks the
reference's full marks, the untouched release's zero and the gradebook CSV.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
from pathlib import Path

import pytest

from mslab.cli import main as cli_main
from mslab.grading import find_exercises, release

SOURCE = Path(__file__).resolve().parents[1] / "exercises"

#: the flat grid's coordinates (the "identity" answer of the cloth deformations)
_FLAT = "np.arange(n_rows * n_cols) % n_cols * spacing, np.arange(n_rows * n_cols) // n_cols * spacing"
#: what each function returns in the "zeros" and the "identity" answer
TRIVIAL = {
    "spring_forces": ("np.zeros_like(x, dtype=float)", "np.array(x, dtype=float)"),
    "spring_jacobian": ("np.zeros((x.size, x.size))", "np.eye(x.size)"),
    "forward_euler_step": ("(np.zeros_like(x), np.zeros_like(v))", "(x, v)"),
    "symplectic_euler_step": ("(np.zeros_like(x), np.zeros_like(v))", "(x, v)"),
    "symplectic_euler_x_step": ("(np.zeros_like(x), np.zeros_like(v))", "(x, v)"),
    "heun_step": ("(np.zeros_like(x), np.zeros_like(v))", "(x, v)"),
    "midpoint_step": ("(np.zeros_like(x), np.zeros_like(v))", "(x, v)"),
    "rk4_tableau": ("(np.zeros((4, 4)), np.zeros(4), np.zeros(4))",
                    "(np.eye(4), np.ones(4) / 4, np.ones(4))"),
    "rk_step": ("(np.zeros_like(x), np.zeros_like(v))", "(x, v)"),
    "verlet_start": ("np.zeros_like(x0)", "x0"),
    "verlet_step": ("np.zeros_like(x)", "x"),
    "leapfrog_start": ("np.zeros_like(v0)", "v0"),
    "leapfrog_step": ("(np.zeros_like(x), np.zeros_like(v_half))", "(x, v_half)"),
    "implicit_euler_fixed_point": ("(np.zeros_like(x), np.zeros_like(v), 1)", "(x, v, 1)"),
    "implicit_euler_newton": ("(np.zeros_like(x), np.zeros_like(v), 1)", "(x, v, 1)"),
    "stability_function": ("np.zeros(np.shape(z), dtype=complex)", "np.ones(np.shape(z), dtype=complex)"),
    "real_stability_interval": ("0.0", "-2.0"),
    "penetration_depth": ("np.zeros(len(x))", "np.array(x[:, -1], dtype=float)"),
    "plane_contact_force": ("np.zeros_like(x, dtype=float)", "np.array(v, dtype=float)"),
    "kinetic_energy": ("0.0", "float(np.sum(v))"),
    "potential_energy": ("0.0", "float(np.sum(x))"),
    "ledger": ("(np.zeros(len(xs)), np.zeros(len(xs)), np.zeros(len(xs)))",
               "(np.ones(len(xs)), np.ones(len(xs)), np.ones(len(xs)))"),
    "band_and_drift": ("(0.0, 0.0)", "(float(error[0]), float(t[0]))"),
    "verdict": ("'bounded'", "'drifting'"),
    "fit_error_model": ("(0.0, 0.0)", "(1.0, 1.0)"),
    "step_for_target": ("0.0", "float(target)"),
    "predicted_cost": ("(0, 0)", "(1, 1)"),
    "cheapest": ("(next(iter(runs)), 0, 0)", "(list(runs)[-1], 1, 1)"),
    "grid_springs": ("np.zeros((0, 2), dtype=int)",
                     "np.stack([np.arange(n_rows * n_cols - 1), np.arange(1, n_rows * n_cols)], axis=1)"),
    "sheared": ("np.zeros((n_rows * n_cols, 2))", f"np.stack([{_FLAT}], axis=1)"),
    "folded": ("np.zeros((n_rows * n_cols, 3))", f"np.stack([{_FLAT}, np.zeros(n_rows * n_cols)], axis=1)"),
    "order3_conditions": ("np.zeros(4)", "np.ones(4)"),
    "kutta_family": ("(np.zeros((3, 3)), np.zeros(3))", "(np.eye(3), np.ones(3) / 3)"),
    "my_method": ("(np.zeros((3, 3)), np.zeros(3))", "(np.eye(3), np.ones(3) / 3)"),
    "rk3_step": ("(np.zeros_like(x), np.zeros_like(v))", "(x, v)"),
}
STRATEGIES = ("zeros", "identity", "raises")


def trivial_version(text: str, strategy: str) -> str:
    """The released file with every ``raise NotImplementedError`` made a trivial answer."""
    out, current = ["import numpy as np"], None
    for line in text.splitlines():
        m = re.match(r"\s*def (\w+)\(", line)
        if m:
            current = m.group(1)
        if line.strip() == "raise NotImplementedError":
            indent = line[: len(line) - len(line.lstrip())]
            if strategy == "raises":
                line = f"{indent}raise RuntimeError('no')"
            else:
                line = f"{indent}return {TRIVIAL[current][STRATEGIES.index(strategy)]}"
        out.append(line)
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def graded_docs(tmp_path_factory) -> tuple[dict, Path]:
    """``mslab grade`` on a class folder: the reference, the untouched release, the trivial answers."""
    base = tmp_path_factory.mktemp("trivial")
    released = base / "release"
    release(SOURCE, released)
    cls = base / "class"
    shutil.copytree(SOURCE, cls / "reference", ignore=shutil.ignore_patterns("__pycache__", "test_*"))
    for strategy in STRATEGIES:
        shutil.copytree(released, cls / strategy)
        for ex in find_exercises(SOURCE):
            path = cls / strategy / ex.name / ex.module
            path.write_text(trivial_version(path.read_text(), strategy))
    shutil.copytree(released, cls / "untouched")
    csv_path = base / "gradebook.csv"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = cli_main(["grade", str(cls), "--source", str(SOURCE), "--json", "--csv", str(csv_path),
                         "--timeout", "10", "--jobs", "2"])
    assert code == 0
    doc = json.loads(buf.getvalue())
    return {d["student"]: d for d in doc["submissions"]}, csv_path


@pytest.fixture(scope="module")
def graded(graded_docs) -> dict:
    return graded_docs[0]


def _passed(doc: dict) -> list[tuple[str, str]]:
    return [(e["name"], t["test"]) for e in doc["exercises"] for t in e["tests"] if t["passed"]]


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_trivial_answers_score_no_more_than_the_release(graded, strategy):
    result = graded[strategy]
    assert graded["untouched"]["total"] == 0
    assert result["total"] <= graded["untouched"]["total"], _passed(result)


def test_reference_solutions_get_full_marks(graded):
    ref = graded["reference"]
    failed = [(e["name"], t["test"], t["reason"])
              for e in ref["exercises"] for t in e["tests"] if not t["passed"]]
    assert failed == []
    expected_max = sum(ex.max_points for ex in find_exercises(SOURCE))
    assert ref["total"] == ref["max"] == expected_max > 0


def test_untouched_release_gets_zero(graded):
    rel = graded["untouched"]
    assert rel["total"] == 0 and rel["max"] > 0
    tests = [t for e in rel["exercises"] for t in e["tests"]]
    public = {t["reason"] for t in tests if t["test"].startswith("test_public")}
    hidden = {t["reason"] for t in tests if t["test"].startswith("test_hidden")}
    assert all("NotImplementedError" in r for r in public), public
    assert hidden == {"hidden test: raised an exception"}  # the runner's phrase, no sandbox text


def test_gradebook_csv(graded_docs):
    results, csv_path = graded_docs
    lines = csv_path.read_text().splitlines()
    header = lines[0].split(",")
    assert header[:3] == ["student", "total", "max"] and len(header) == 3 + len(find_exercises(SOURCE))
    rows = {line.split(",")[0]: line.split(",") for line in lines[1:]}
    assert rows["reference"][1] == rows["reference"][2] == f"{results['reference']['max']:g}"
    assert rows["untouched"][1] == "0"
    assert not list(csv_path.parent.glob(".gradebook-*"))  # no temporary left behind


def test_every_exercise_has_a_test_drawn_at_grading():
    for ex in find_exercises(SOURCE):
        hidden = ex.tests["test_hidden.py"]
        assert "default_rng()" in hidden and "drawn_at_grading" in hidden, ex.name
