"""A sandbox gets the trusted acceleration only where the tests hand the student a problem.

``mslab/grading/problems.py`` computes spring forces and their Jacobian for the step
exercises: that is exercise 01's answer. An outside check (issue 36, D1) graded a file that
built a ``Problem`` inside the sandbox (imported by the sandbox before the student's file)
and returned its forces: 16/16 for exercise 01 without Hooke's law. Now the sandbox imports
it only when a problem arrives, and an exercise whose tests name no problem
(:attr:`mslab.grading.layout.Exercise.hands_problems`) gets a sandbox without the file. In
the namespace modes the student sees only the sandbox's files; the rlimits modes read what
the grader's user or any user reads (README's table), so they are not tested here.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from mslab.grading import grade
from mslab.grading.isolation import _probe
from mslab.grading.layout import find_exercises

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
EX, MODULE = "01_spring_force", "spring_force.py"
MODES = [m for m in ("bwrap", "namespaces") if sys.platform.startswith("linux") and _probe(m)]

#: exercise 01 without Hooke's law: the trusted problem's forces and Jacobian, however reached
CHEAT = '''
import sys

import numpy as np


def _problem_class():
    try:
        from problems import Problem
        return Problem
    except ImportError:
        pass
    for module in list(sys.modules.values()):
        if hasattr(module, "Problem"):
            return module.Problem
    import __main__
    return __main__.Problem


def _problem(x, springs, stiffness, rest_length):
    p = _problem_class()("oscillator")
    n, dim = np.shape(x)
    p.springs, p.stiffness = np.asarray(springs), np.asarray(stiffness, dtype=float)
    p.rest_length = np.asarray(rest_length, dtype=float)
    p.mass, p.inv_mass, p.gravity, p.gamma = np.ones(n), np.ones(n), np.zeros(dim), 0.0
    return p


def spring_forces(x, springs, stiffness, rest_length):
    return _problem(x, springs, stiffness, rest_length)(x)


def spring_jacobian(x, springs, stiffness, rest_length):
    return _problem(x, springs, stiffness, rest_length).jacobians(x)[0]
'''


def _public_tests() -> list:
    spec = importlib.util.spec_from_file_location("withheld_public_01", SOURCE / EX / "test_public.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return [fn for name, fn in vars(module).items() if name.startswith("test_")]


def test_the_cheat_is_real_where_the_problem_is_importable(tmp_path, monkeypatch):
    """With ``problems.py`` importable (as it was in every sandbox) the cheat passes every public test."""
    monkeypatch.syspath_prepend(str(ROOT / "mslab" / "grading"))
    (tmp_path / "cheat.py").write_text(CHEAT)
    spec = importlib.util.spec_from_file_location("cheat", tmp_path / "cheat.py")
    cheat = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cheat)
    tests = _public_tests()
    assert len(tests) >= 4
    for test in tests:
        test(cheat)
    monkeypatch.delitem(sys.modules, "problems", raising=False)


def test_only_exercises_that_hand_over_a_problem_get_the_file():
    hands = {ex.name[:2]: ex.hands_problems for ex in find_exercises(SOURCE)}
    assert not hands["01"] and not hands["07"] and not hands["08"]  # forces, stability, contact
    assert all(hands[n] for n in ("02", "03", "04", "05", "06", "09", "12"))  # handed a problem


@pytest.mark.parametrize("text, hands", [
    ("from mslab.grading.problems import problem\n", True),
    ("import mslab.grading.problems as p\n", True),
    ("def test():\n    from mslab.grading.checks import step_order\n", True),
    ("from mslab.grading import checks\n", True),
    ("from mslab.grading.checks import close, require\n", False),
    ("# a problem, step_order, swinging_spring: words in a comment\nX = 'problem'\n", False),
    ("def broken(:\n", True),  # does not parse: the conservative answer
])
def test_a_test_hands_a_problem_only_by_importing_one(text, hands):
    """Only an import counts (the earlier rule read any word "problem", in a comment too)."""
    from mslab.grading.layout import Exercise, imports_problems

    assert imports_problems(text) is hands
    assert Exercise("01_x", Path("."), "x.py", tests={"test_public.py": text}).hands_problems is hands


@pytest.mark.skipif(not MODES, reason="needs bubblewrap or unprivileged user namespaces")
@pytest.mark.parametrize("mode", MODES)
def test_a_graded_file_cannot_reach_the_trusted_problem(tmp_path, mode):
    for name, text in (("cheat", CHEAT), ("honest", (SOURCE / EX / MODULE).read_text())):
        folder = tmp_path / "class" / name / EX
        folder.mkdir(parents=True)
        (folder / MODULE).write_text(text)
    results = {r.student: r for r in grade([tmp_path / "class"], source=SOURCE, jobs=1, only=[EX],
                                           isolation=mode, require_isolation=True)}
    (honest,), (cheat,) = results["honest"].exercises, results["cheat"].exercises
    assert honest.total == honest.max_points > 0
    assert cheat.total == 0.0, [(t.test, t.reason) for t in cheat.tests if t.passed]
    assert all(not t.grader_fault for t in cheat.tests)


#: exercise 04 with rk_step honest and rk4_tableau returning the last four-stage tableau it was handed
KEEPER = (SOURCE / "04_rk4_tableau" / "rk_tableau.py").read_text().replace(
    "def rk_step(", "_KEPT = []\n\n\ndef rk_step(", 1) + '''

_honest_rk_step = rk_step


def rk_step(x, v, accel, dt, A, b):
    if len(b) == 4:
        _KEPT.append((A.copy(), b.copy()))
    return _honest_rk_step(x, v, accel, dt, A, b)


def rk4_tableau():
    if not _KEPT:
        raise NotImplementedError
    A, b = _KEPT[-1]
    return A, b, A.sum(axis=1)
'''


def test_no_test_hands_over_what_a_later_test_of_its_group_asks_for(tmp_path):
    """Outside check: exercise 04's hidden tests handed RK4's tableau to rk_step before asking for it."""
    folder = tmp_path / "class" / "keeper" / "04_rk4_tableau"
    folder.mkdir(parents=True)
    (folder / "rk_tableau.py").write_text(KEEPER)
    (result,) = grade([tmp_path / "class"], source=SOURCE, jobs=1, only=["04_rk4_tableau"])
    (ex,) = result.exercises
    tableau_tests = [t for t in ex.tests if "rk4_tableau" in t.test]
    assert len(tableau_tests) == 2 and not any(t.passed for t in tableau_tests), \
        [(t.test, t.passed) for t in tableau_tests]
    assert any(t.passed for t in ex.tests if "rk_step" in t.test)  # the honest part still scores
