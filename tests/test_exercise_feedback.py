"""Common mistakes, planted in the reference solutions, are named and cost only their own tests.

Issue 36, item 6. ``tests/exercise_mistakes.py`` lists 2-5 common mistakes per exercise
(the symplectic Eulers swapped, a spring force's sign, RK4's weights misordered, Newton's
matrix without the drag term, ...). For each, every test of the exercise runs on the
planted file in this process (the same test functions the grader runs, called with the
module as ``student``): exactly the tests of that idea fail, and the public tests listed
name the mistake in one line that fits the grade report (200 characters). One grading by
the real grader (``mslab.grading.grade``) checks that those lines reach the report as
they are, and that no hidden test says more than its fixed phrase.
"""

from __future__ import annotations

import importlib.util
import re
import types
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from exercise_mistakes import MISTAKES, Mistake

from mslab.grading import grade
from mslab.grading.remote import PHRASES

SOURCE = Path(__file__).resolve().parents[1] / "exercises"
REPORT_WIDTH = 200  # mslab.grading.report shows a reason up to this many characters


@cache
def functions_of(exercise: str, filename: str) -> dict:
    """The test functions of one test file of an exercise, imported once."""
    path = SOURCE / exercise / filename
    spec = importlib.util.spec_from_file_location(f"feedback_{exercise}_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return {f"{filename}::{name}": fn for name, fn in vars(module).items()
            if name.startswith("test_") and callable(fn)}


def planted(mistake: Mistake) -> types.ModuleType:
    """The exercise's reference file with the mistake planted, as a module."""
    module = types.ModuleType(Path(mistake.module).stem)
    exec(compile(mistake.text(SOURCE), mistake.module, "exec"), module.__dict__)  # noqa: S102 - our own text
    return module


def outcomes(mistake: Mistake) -> dict[str, str | None]:
    """Each test's failure line (None if it passed), run on the planted module."""
    student = planted(mistake)
    result: dict[str, str | None] = {}
    for filename in ("test_public.py", "test_hidden.py"):
        for name, fn in functions_of(mistake.exercise, filename).items():
            try:
                with np.errstate(all="ignore"):  # a planted 0/0 (unregularised friction at rest) is quiet
                    fn(student)
                result[name] = None
            except AssertionError as err:
                result[name] = str(err).strip().splitlines()[0] if str(err).strip() else "assertion failed"
            except Exception as err:  # noqa: BLE001 - the student's own exception fails the test
                result[name] = f"{type(err).__name__}: {err}"
    return result


@pytest.mark.parametrize("mistake", MISTAKES, ids=[m.name for m in MISTAKES])
def test_a_planted_mistake_fails_its_own_tests_and_is_named(mistake):
    out = outcomes(mistake)
    assert mistake.fails <= out.keys(), sorted(mistake.fails - out.keys())
    failed = {name for name, reason in out.items() if reason is not None}
    required = mistake.fails - mistake.maybe  # a test on drawn inputs may pass by chance on a corner case
    assert required <= failed, f"not failed: {sorted(required - failed)}"
    assert failed <= mistake.fails, f"failed beyond the mistake's idea: {sorted(failed - mistake.fails)}"
    for name, words in mistake.named.items():
        reason = out[name]
        assert reason is not None and words in reason, (name, reason)
        assert "\n" not in reason and len(reason) <= REPORT_WIDTH, (name, len(reason), reason)


def test_every_exercise_has_planted_mistakes_named():
    exercises = sorted(p.name for p in SOURCE.iterdir() if re.match(r"^\d\d_", p.name))
    for exercise in exercises:
        mine = [m for m in MISTAKES if m.exercise == exercise]
        assert len(mine) >= 2 and any(m.named for m in mine), exercise


#: graded by the real grader: swapped methods, a wrong start-up (its hidden tests re-isolated),
#: Newton's matrix without the drag term, RK4's weights misordered
GRADED = ("02 symplectic Eulers swapped", "03 Heun and midpoint swapped", "05 Verlet start without h^2/2 a",
          "06 Newton matrix without the damping term", "04 RK4 weights misordered")


def test_the_grader_reports_the_same_one_line_reasons(tmp_path):
    chosen = [m for m in MISTAKES if m.name in GRADED]
    for k, m in enumerate(chosen):
        folder = tmp_path / "class" / f"s{k}" / m.exercise
        folder.mkdir(parents=True)
        folder.joinpath(m.module).write_text(m.text(SOURCE))
    results = {Path(r.submission).name: r for r in grade([tmp_path / "class"], source=SOURCE, jobs=2,
                                                         only=sorted({m.exercise for m in chosen}))}
    phrases = {f"hidden test: {p}" for p in PHRASES.values()}
    for k, m in enumerate(chosen):
        (ex,) = [e for e in results[f"s{k}"].exercises if e.name == m.exercise]
        local = outcomes(m)
        failed = {t.test for t in ex.tests if not t.passed}
        assert failed - m.maybe == {name for name, why in local.items() if why is not None} - m.maybe, m.name
        assert failed <= m.fails, (m.name, failed)
        assert ex.total == ex.max_points - sum(t.max_points for t in ex.tests if t.test in failed)
        for t in ex.tests:
            if t.passed:
                continue
            if t.test.startswith("test_hidden"):
                assert t.reason in phrases, t.reason
            else:
                assert t.reason == local[t.test], (t.reason, local[t.test])
        for name, words in m.named.items():
            assert words in next(t.reason for t in ex.tests if t.test == name)
