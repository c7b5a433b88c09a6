"""The grader: every exercise of every submission, in parallel, scored from trusted results.

For each (submission, exercise) pair the grader starts one test runner
(:mod:`mslab.grading.runner`) with a fresh random nonce, the instructor's tests (read from
the *source* tree once, never from the submission) and the student's single source file.
The runner runs the tests in its own process and the student's code in a sandbox
(:mod:`mslab.grading.sandbox`); only the runner's nonce-tagged line counts. Points and
the list of tests come from the grader's own reading of the test files, so a runner that
crashes, hangs or reports nonsense can only lose points, never add any.
"""

from __future__ import annotations

import json
import os
import secrets
import signal
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from mslab.grading.layout import Exercise, expand_submissions, find_exercises, read_student_file

#: seconds a runner may need beyond its tests' time limits (interpreter, pytest, imports)
RUNNER_SLACK = 60.0
#: bytes of runner output the grader reads at most
MAX_RUNNER_OUTPUT = 4 * 1024 * 1024


@dataclass
class TestResult:
    test: str
    points: float
    max_points: float
    passed: bool
    reason: str


@dataclass
class ExerciseResult:
    name: str
    tests: list[TestResult] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    @property
    def total(self) -> float:
        return float(sum(t.points for t in self.tests))

    @property
    def max_points(self) -> float:
        return float(sum(t.max_points for t in self.tests))


@dataclass
class SubmissionResult:
    submission: str
    student: str
    exercises: list[ExerciseResult] = field(default_factory=list)

    @property
    def total(self) -> float:
        return float(sum(e.total for e in self.exercises))

    @property
    def max_points(self) -> float:
        return float(sum(e.max_points for e in self.exercises))

    def to_dict(self) -> dict:
        return {
            "student": self.student, "submission": self.submission,
            "total": self.total, "max": self.max_points,
            "exercises": [{"name": e.name, "total": e.total, "max": e.max_points, "errors": e.errors,
                           "tests": [{"test": t.test, "points": t.points, "max": t.max_points,
                                      "passed": t.passed, "reason": t.reason} for t in e.tests]}
                          for e in self.exercises],
        }


def _run_runner(job: dict, wall_limit: float) -> tuple[dict | None, str]:
    """Start one runner, feed it the job, return its result (or None and why not)."""
    env = dict(os.environ, PYTEST_DISABLE_PLUGIN_AUTOLOAD="1", PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTEST_ADDOPTS", None)
    proc = subprocess.Popen([sys.executable, "-E", "-s", "-P", "-m", "mslab.grading.runner"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            start_new_session=True, env=env, cwd=os.path.abspath(os.sep))
    try:
        out, _ = proc.communicate(json.dumps(job).encode(), timeout=wall_limit)
    except subprocess.TimeoutExpired:
        _killpg(proc)
        return None, f"grading this exercise took longer than {wall_limit:.0f} s"
    finally:
        _killpg(proc)
    for line in out[:MAX_RUNNER_OUTPUT].decode(errors="replace").splitlines():
        if line.startswith(job["nonce"] + " "):
            try:
                return json.loads(line[len(job["nonce"]) + 1:]), ""
            except ValueError:
                break
    return None, f"the test runner gave no result (exit code {proc.returncode})"


def _killpg(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()


def grade_exercise(submission: Path, exercise: Exercise, timeout: float = 10.0,
                   memory_mb: int = 1024) -> ExerciseResult:
    """Grade one exercise of one submission (runs the tests in a runner subprocess)."""
    source, why = read_student_file(submission, exercise)
    result = ExerciseResult(exercise.name)
    outcome: dict = {}
    if source is None:
        reason_all = why
    else:
        job = {"nonce": secrets.token_hex(16), "module": exercise.module, "student_source": source,
               "tests": exercise.tests, "timeout": timeout, "memory_mb": memory_mb,
               "cpu_s": int(timeout * len(exercise.points) + 30)}
        wall = timeout * (len(exercise.points) + 1) + RUNNER_SLACK
        report, why = _run_runner(job, wall)
        reason_all = why
        if report is not None:
            outcome = report.get("results", {}) if isinstance(report.get("results"), dict) else {}
            result.errors = [str(e)[:300] for e in report.get("errors", [])][:10]
            reason_all = result.errors[0] if result.errors else "not run"
    for test, max_points in exercise.points.items():
        entry = outcome.get(test) if isinstance(outcome.get(test), dict) else None
        passed = bool(entry and entry.get("passed") is True and not result.errors)
        reason = "ok" if passed else str(entry.get("reason", "failed"))[:200] if entry else reason_all
        result.tests.append(TestResult(test, max_points if passed else 0.0, max_points, passed, reason))
    if source is None:
        result.errors = [why]
    return result


def grade(paths, source: str | Path = "exercises", jobs: int | None = None, timeout: float = 10.0,
          memory_mb: int = 1024, only: list[str] | None = None) -> list[SubmissionResult]:
    """Grade submissions (folders of exercise folders, or classes of such folders).

    Parameters
    ----------
    paths : list of path
        Each is one submission or a folder of submissions ``<class>/<student>/``.
    source : path
        The instructor's tree: the tests and the list of exercises come from here.
    jobs : int
        Runners in parallel (default: number of cores).
    timeout : float
        Seconds per test (the student's calls of one test together).
    only : list of str, optional
        Grade only these exercise folders.
    """
    exercises = find_exercises(source)
    if only:
        unknown = set(only) - {e.name for e in exercises}
        if unknown:
            raise ValueError(f"unknown exercise(s): {', '.join(sorted(unknown))}")
        exercises = [e for e in exercises if e.name in only]
    submissions = expand_submissions(paths, exercises)
    pairs = [(s, e) for s in submissions for e in exercises]
    with ThreadPoolExecutor(max_workers=max(1, jobs or os.cpu_count() or 1)) as pool:
        done = list(pool.map(lambda p: grade_exercise(p[0], p[1], timeout, memory_mb), pairs))
    results = []
    for k, sub in enumerate(submissions):
        res = SubmissionResult(str(sub), sub.resolve().name)
        res.exercises = done[k * len(exercises):(k + 1) * len(exercises)]
        results.append(res)
    return results


def format_report(result: SubmissionResult) -> str:
    """The human-readable score sheet of one submission."""
    lines = [f"{result.student}  ({result.submission})"]
    for ex in result.exercises:
        lines.append(f"  {ex.name}: {ex.total:g}/{ex.max_points:g}")
        for t in ex.tests:
            mark = "pass" if t.passed else "FAIL"
            tail = "" if t.passed else f"  {t.reason}"
            lines.append(f"    {t.points:>4g}/{t.max_points:<4g} {mark}  {t.test}{tail}")
    lines.append(f"  total: {result.total:g}/{result.max_points:g}")
    return "\n".join(lines)


def gradebook_rows(results: list[SubmissionResult]) -> list[list]:
    """CSV rows: header, then one row per student (total, max, one column per exercise)."""
    names = [e.name for e in results[0].exercises] if results else []
    rows: list[list] = [["student", "total", "max", *names]]
    for r in results:
        rows.append([r.student, f"{r.total:g}", f"{r.max_points:g}", *(f"{e.total:g}" for e in r.exercises)])
    return rows
