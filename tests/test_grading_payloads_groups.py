"""The runner's side of the trust boundary: sandboxes per test group, bounded checks (issue 35).

Hidden and public tests never share a sandbox (item 4).
One sandbox process once served every test of an exercise, the hidden tests first: a
public test's quoted message carried the shape and first value of every hidden call. Here
a student records the inputs of every call (in memory and in a file beside its module)
and sends them back in the message of every public test: a marker planted in a hidden
test's inputs must appear in no output, while the same kind of marker in a public test
does (so the leak works, and this test can fail).

Whatever a test's checks do with the answers, they cost the runner a bounded CPU time: an
endless check fails as a CPU timeout and the next test runs.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

from mslab.grading import grade
from mslab.grading.isolation import detect
from mslab.grading.report import format_report

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET, MODULE = "07_stability_function", "stability_function.py"
HIDDEN_MARK, PUBLIC_MARK = "6180339", "2718281"

MARKED = """

@pytest.mark.points(1)
def test_marked_{kind}(student):
    from mslab.grading.checks import check_array  # the exercise's own tests need not import it

    A = np.array([[0.0, 0.0], [0.5, 0.0]])
    b = np.array([0.5, 0.5])
    z = np.array([-0.{mark} + 0.5j])
    check_array(student.stability_function(A, b, z), 1.0 + z + z * z / 4, rtol=1e-10, atol=1e-12, what="R")
"""

#: the reference solution, wrapped: every call's inputs recorded; public calls fail quoting them all
RECORDER = r"""

import os as _os
import re as _re
import numpy as _np

_SEEN = []
_LOG = _os.path.join(_os.path.dirname(_os.path.abspath(__file__)), "seen.log")


def _record(args):
    for a in args:   # the short decimals among the inputs (the fixed inputs an attacker wants)
        _SEEN.extend(_re.findall(r"0\.\d{7}(?!\d)", repr(_np.asarray(a).tolist())))
    try:
        with open(_LOG, "a") as fh:
            fh.write(" ".join(_SEEN[-4:]) + "\n")
        with open(_LOG) as fh:
            return fh.read().split()
    except OSError:
        return []


_real = stability_function


def stability_function(A, b, z):
    earlier = _record((A, b, z))
    seen = " ".join(sorted(set(_SEEN + earlier)))
    if any("{public}" in s for s in _SEEN):
        raise ValueError("seen: " + seen)
    return _real(A, b, z)
"""


def test_a_public_message_carries_nothing_from_a_hidden_input(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(SOURCE / TARGET, src / TARGET, ignore=shutil.ignore_patterns("__pycache__"))
    for kind, mark in (("hidden", HIDDEN_MARK), ("public", PUBLIC_MARK)):
        path = src / TARGET / f"test_{kind}.py"
        path.write_text(path.read_text() + MARKED.format(kind=kind, mark=mark))
    student = tmp_path / "class" / "leaker" / TARGET
    student.mkdir(parents=True)
    reference = (SOURCE / TARGET / MODULE).read_text()
    recorder = textwrap.dedent(RECORDER).replace("{public}", PUBLIC_MARK)
    student.joinpath(MODULE).write_text(reference + recorder)
    (result,) = grade([student.parent], source=src, jobs=1, timeout=5.0, only=[TARGET])
    tests = {t.test: t for t in result.exercises[0].tests}
    leak = tests["test_public.py::test_marked_public"]
    assert not leak.passed and PUBLIC_MARK in leak.reason, leak.reason   # the leak works ...
    outputs = format_report(result) + json.dumps(result.to_dict())
    assert HIDDEN_MARK not in outputs                                     # ... and carries no hidden input
    assert tests["test_hidden.py::test_marked_hidden"].passed     # the hidden tests ran, in their sandbox


SLOW_CHECK = """
import pytest

MODULE = "m"


@pytest.mark.points(1)
def test_a_check_that_never_ends(student):
    n = student.answer()
    while True:  # an instructor's check made endless by what the student answered
        n = (n * 3 + 1) % 1000003


@pytest.mark.points(1)
def test_the_next_test_still_runs(student):
    assert student.answer() == 7
"""


def test_the_runner_spends_bounded_cpu_on_the_checks_of_one_test():
    job = {"nonce": "n0nce", "timeout": 5.0, "isolation": detect("auto"), "check_cpu": 1.0,
           "items": [{"key": "k", "module": "m.py", "student_source": "def answer():\n    return 7\n",
                      "tests": {"test_hidden.py": SLOW_CHECK}}]}
    proc = subprocess.run([sys.executable, "-m", "mslab.grading.runner"], input=json.dumps(job),
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("n0nce ")]
    assert len(lines) == 1, proc.stdout + proc.stderr
    results = json.loads(lines[0].split(" ", 1)[1])["outcome"]["results"]
    slow = results["test_hidden.py::test_a_check_that_never_ends"]
    assert slow["passed"] is False and slow["kind"] == "cpu", slow
    assert slow["reason"] == "timed out (CPU time limit)"
    assert results["test_hidden.py::test_the_next_test_still_runs"]["passed"] is True
