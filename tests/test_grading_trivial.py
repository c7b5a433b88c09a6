"""Trivial answers score what the untouched release scores: nothing.

Zeros, "identity" steps that return their input, and functions that raise RuntimeError
are graded for every exercise, next to a classmate with the reference solutions who must
keep full marks (issue 10: weak tests accepted 14/98 of such answers).
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from mslab.grading import find_exercises, grade, release

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
def graded(tmp_path_factory):
    base = tmp_path_factory.mktemp("trivial")
    released = base / "release"
    release(SOURCE, released)
    cls = base / "class"
    shutil.copytree(SOURCE, cls / "victim", ignore=shutil.ignore_patterns("__pycache__", "test_*"))
    for strategy in STRATEGIES:
        shutil.copytree(released, cls / strategy)
        for ex in find_exercises(SOURCE):
            path = cls / strategy / ex.name / ex.module
            path.write_text(trivial_version(path.read_text(), strategy))
    shutil.copytree(released, cls / "release")
    return {r.student: r for r in grade([cls], source=SOURCE, jobs=2, timeout=10.0)}


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_trivial_answers_score_no_more_than_the_release(graded, strategy):
    result = graded[strategy]
    passed = [(e.name, t.test) for e in result.exercises for t in e.tests if t.passed]
    assert graded["release"].total == 0
    assert result.total <= graded["release"].total, passed


def test_the_reference_keeps_full_marks_next_to_them(graded):
    victim = graded["victim"]
    failed = [(e.name, t.test, t.reason) for e in victim.exercises for t in e.tests if not t.passed]
    assert failed == [] and victim.total == victim.max_points > 0


def test_every_exercise_has_a_test_drawn_at_grading():
    for ex in find_exercises(SOURCE):
        hidden = ex.tests["test_hidden.py"]
        assert "default_rng()" in hidden and "drawn_at_grading" in hidden, ex.name
