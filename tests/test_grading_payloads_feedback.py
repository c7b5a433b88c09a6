"""Exercise feedback that teaches (issue 36, item 6).

- A student's local run shows one line per failure, no traceback, and names a common
  mistake (the planted mistakes of every exercise, graded: ``test_exercise_feedback.py``).
- Every exercise's README states the points the grader awards (public, hidden, total),
  read here from the tests themselves.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

from mslab.grading import find_exercises

SOURCE = Path(__file__).resolve().parents[1] / "exercises"


def test_readme_points_are_the_points_of_the_tests():
    for ex in find_exercises(SOURCE):
        text = (SOURCE / ex.name / "README.md").read_text()
        public = sum(p for k, p in ex.points.items() if k.startswith("test_public"))
        hidden = sum(p for k, p in ex.points.items() if k.startswith("test_hidden"))
        total = re.search(r"^## Grading \((\d+) points\)", text, re.M)
        assert total and int(total.group(1)) == ex.max_points, (ex.name, ex.max_points)
        assert re.search(rf"\bPublic \({public:g}\)", text), (ex.name, "public", public)
        assert re.search(rf"\bHidden \({hidden:g}\)", text), (ex.name, "hidden", hidden)


def test_a_local_run_gives_one_line_per_failure_not_a_traceback(tmp_path):
    # what a student sees running the public tests on their folder
    for name in ("pytest.ini", "conftest.py"):
        shutil.copy(SOURCE / name, tmp_path / name)
    shutil.copytree(SOURCE / "02_euler_steps", tmp_path / "02_euler_steps",
                    ignore=shutil.ignore_patterns("test_hidden*", "__pycache__"))
    module = tmp_path / "02_euler_steps" / "euler_steps.py"
    module.write_text(module.read_text() + "\n\n_a, _b = symplectic_euler_step, symplectic_euler_x_step\n"
                      "symplectic_euler_step, symplectic_euler_x_step = _b, _a\n")
    out = subprocess.run([sys.executable, "-m", "pytest", "02_euler_steps", "-p", "no:randomly"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=300).stdout
    assert "2 failed, 1 passed" in out, out
    assert out.count("likely mistake: the two symplectic Eulers are swapped") >= 2, out
    assert not [line for line in out.splitlines() if line.startswith((">", "    def ", "Traceback"))], out
