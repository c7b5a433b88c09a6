"""Exercise feedback that teaches (issue 36, item 6).

- Each test isolates one idea: a wrong start-up of exercise 05 fails the start-up's tests,
  not the tests of the steps (which start from the library's start-up).
- A common mistake is named in one line: the two symplectic Eulers swapped, Heun and the
  midpoint method swapped; a student's local run shows one line per failure, no traceback.
- Every exercise's README states the points the grader awards (public, hidden, total),
  read here from the tests themselves.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

from mslab.grading import find_exercises, grade

SOURCE = Path(__file__).resolve().parents[1] / "exercises"


def graded(tmp_path: Path, exercise: str, module: str, text: str) -> dict:
    (tmp_path / "s" / exercise).mkdir(parents=True)
    (tmp_path / "s" / exercise / module).write_text(text)
    (result,) = grade([tmp_path / "s"], source=SOURCE, jobs=1, only=[exercise])
    return {t.test: t for t in result.exercises[0].tests}


def test_readme_points_are_the_points_of_the_tests():
    for ex in find_exercises(SOURCE):
        text = (SOURCE / ex.name / "README.md").read_text()
        public = sum(p for k, p in ex.points.items() if k.startswith("test_public"))
        hidden = sum(p for k, p in ex.points.items() if k.startswith("test_hidden"))
        total = re.search(r"^## Grading \((\d+) points\)", text, re.M)
        assert total and int(total.group(1)) == ex.max_points, (ex.name, ex.max_points)
        assert re.search(rf"\bPublic \({public:g}\)", text), (ex.name, "public", public)
        assert re.search(rf"\bHidden \({hidden:g}\)", text), (ex.name, "hidden", hidden)


def test_a_wrong_start_fails_only_the_tests_of_the_start(tmp_path):
    solution = (SOURCE / "05_verlet_leapfrog" / "verlet_leapfrog.py").read_text()
    # a common slip: the backward Taylor step without its h^2/2 term
    wrong = solution + "\n\ndef verlet_start(x0, v0, accel, dt):\n    return x0 - dt * v0\n"
    tests = graded(tmp_path, "05_verlet_leapfrog", "verlet_leapfrog.py", wrong)
    failed = {k for k, t in tests.items() if not t.passed}
    assert failed == {"test_public.py::test_verlet_start_is_the_backward_taylor_step",
                      "test_hidden.py::test_verlet_and_leapfrog_give_the_same_positions"}, failed
    reason = tests["test_public.py::test_verlet_start_is_the_backward_taylor_step"].reason
    assert "likely mistake: the h^2/2 a term is missing" in reason, reason


def test_swapped_methods_are_named(tmp_path):
    solution = (SOURCE / "02_euler_steps" / "euler_steps.py").read_text()
    swapped = solution + ("\n\n_a, _b = symplectic_euler_step, symplectic_euler_x_step\n"
                          "symplectic_euler_step, symplectic_euler_x_step = _b, _a\n")
    tests = graded(tmp_path, "02_euler_steps", "euler_steps.py", swapped)
    for name in ("test_symplectic_euler_matches_the_library", "test_symplectic_euler_x_matches_the_library"):
        reason = tests[f"test_public.py::{name}"].reason
        assert "likely mistake: the two symplectic Eulers are swapped" in reason, reason
        assert "\n" not in reason
    solution = (SOURCE / "03_heun_midpoint" / "heun_midpoint.py").read_text()
    swapped = solution + "\n\n_a, _b = heun_step, midpoint_step\nheun_step, midpoint_step = _b, _a\n"
    tests = graded(tmp_path / "h", "03_heun_midpoint", "heun_midpoint.py", swapped)
    assert "likely mistake: this is the midpoint method's step" in \
        tests["test_public.py::test_heun_matches_the_library"].reason
    assert "likely mistake: this is Heun's step" in \
        tests["test_public.py::test_midpoint_matches_the_library"].reason


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
