"""The grader: every exercise of every submission, in parallel, scored from trusted results.

The (submission, exercise) pairs are dealt to a few test runners
(:mod:`mslab.grading.runner`), each started with a fresh random nonce, the instructor's
tests (read from the *source* tree once, never from the submission) and the students'
single source files.
The runner runs the tests in its own process and the student's code in a sandbox
(:mod:`mslab.grading.sandbox`); only the runner's nonce-tagged line counts. Points and
the list of tests come from the grader's own reading of the test files, so a runner that
crashes, hangs or reports nonsense can only lose points, never add any.
"""

from __future__ import annotations

import json
import os
import secrets
import selectors
import signal
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from mslab.grading.layout import Exercise, expand_submissions, find_exercises, read_student_file
from mslab.grading.remote import set_not_dumpable

#: seconds a runner may need beyond its tests' time limits (interpreter, pytest, imports)
RUNNER_SLACK = 60.0
#: the folder holding the grader's own ``mslab`` (the runner imports the same code)
PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])
RUNNER_BOOT = "import sys; sys.path.insert(0, {root!r}); from mslab.grading.runner import main; main()"
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


def _run_runner(job: dict, wall_limit: float) -> tuple[dict, str]:
    """Start one runner, feed it the job; ``{key: outcome}`` of the items it finished, and why not all."""
    env = dict(os.environ, PYTEST_DISABLE_PLUGIN_AUTOLOAD="1", PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTEST_ADDOPTS", None)
    proc = subprocess.Popen([sys.executable, "-E", "-s", "-P", "-c", RUNNER_BOOT.format(root=PACKAGE_ROOT)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            start_new_session=True, env=env, cwd=os.path.abspath(os.sep))
    why = ""
    try:
        # wait for "ready": the runner is non-dumpable before the nonce reaches its stdin
        sel = selectors.DefaultSelector()
        sel.register(proc.stdout, selectors.EVENT_READ)
        ready = sel.select(timeout=RUNNER_SLACK)
        sel.close()
        if not ready or proc.stdout.readline() != b"ready\n":
            return {}, "the test runner did not start"
        out, _ = proc.communicate(json.dumps(job).encode(), timeout=wall_limit)
    except subprocess.TimeoutExpired:
        _killpg(proc)
        out = b""
        why = f"grading took longer than {wall_limit:.0f} s"
    finally:
        _killpg(proc)
    done = {}
    prefix = job["nonce"] + " "
    for line in out[:MAX_RUNNER_OUTPUT].decode(errors="replace").splitlines():
        if not line.startswith(prefix):
            continue
        try:
            msg = json.loads(line[len(prefix):])
        except ValueError:
            continue
        if isinstance(msg, dict) and isinstance(msg.get("outcome"), dict):
            done[str(msg.get("key"))] = msg["outcome"]
    if len(done) < len(job["items"]) and not why:
        why = f"the test runner stopped (exit code {proc.returncode})"
    return done, why


def _killpg(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()


def _score(exercise: Exercise, outcome: dict, errors: list[str], reason_all: str) -> ExerciseResult:
    """Points of one exercise from the runner's outcomes; the test list is the grader's own."""
    result = ExerciseResult(exercise.name, errors=errors)
    for test, max_points in exercise.points.items():
        entry = outcome.get(test) if isinstance(outcome.get(test), dict) else None
        passed = bool(entry and entry.get("passed") is True and not errors)
        if passed:
            reason = "ok"
        elif entry and not errors:
            reason = str(entry.get("reason", "failed"))[:200]
        else:
            reason = errors[0] if errors else reason_all
        result.tests.append(TestResult(test, max_points if passed else 0.0, max_points, passed, reason))
    return result


def _run_items(items: list[dict], timeout: float, memory_mb: int) -> tuple[dict, str]:
    """Run items in one runner: ``({key: outcome}, why some are missing)``."""
    job = {"nonce": secrets.token_hex(16), "timeout": timeout, "memory_mb": memory_mb,
           "import_timeout": max(30.0, timeout), "items": items}
    wall = sum(timeout * (it["n_tests"] + 1) + max(30.0, timeout) for it in items) + RUNNER_SLACK
    return _run_runner(job, wall)


def _run_chunk(items: list[dict], timeout: float, memory_mb: int) -> dict:
    """Run a chunk of items: ``{key: (outcome or None, why)}``.

    The runner grades items in order and reports each as it finishes. If it dies (a
    student's process may kill it) or overruns, the first unfinished item is the suspect:
    it is re-run alone, and the items after it get a fresh runner, so one submission can
    never cost another one points.
    """
    out: dict = {}
    pending = list(items)
    while pending:
        done, why = _run_items(pending, timeout, memory_mb)
        for it in pending:
            if it["key"] in done:
                out[it["key"]] = (done[it["key"]], "")
        rest = [it for it in pending if it["key"] not in done]
        if not rest:
            break
        suspect = rest[0]
        if len(pending) == 1:  # it already ran alone
            out[suspect["key"]] = (None, why or "not graded")
            break
        alone, why_alone = _run_items([suspect], timeout, memory_mb)
        out[suspect["key"]] = (alone.get(suspect["key"]), why_alone or "not graded")
        pending = rest[1:]
    return out


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
        Runners in parallel (default: number of cores). The (submission, exercise) items
        are dealt to ``jobs`` runners; each grades its items in turn.
    timeout : float
        Seconds per test (the student's calls of one test together).
    only : list of str, optional
        Grade only these exercise folders.
    """
    set_not_dumpable()  # no process of ours may read the nonces from our memory
    exercises = find_exercises(source)
    if only:
        unknown = set(only) - {e.name for e in exercises}
        if unknown:
            raise ValueError(f"unknown exercise(s): {', '.join(sorted(unknown))}")
        exercises = [e for e in exercises if e.name in only]
    submissions = expand_submissions(paths, exercises)
    jobs = max(1, jobs or os.cpu_count() or 1)
    sources, items = {}, []
    for k, sub in enumerate(submissions):
        for ex in exercises:
            text, why = read_student_file(sub, ex)
            sources[(k, ex.name)] = why
            if text is not None:
                items.append({"key": f"{k}:{ex.name}", "name": ex.name, "module": ex.module,
                              "student_source": text, "tests": ex.tests, "n_tests": len(ex.points),
                              "cpu_s": int(timeout * len(ex.points) + 60)})
    chunks = [items[j::jobs] for j in range(jobs) if items[j::jobs]]
    outcomes: dict = {}
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        for part in pool.map(lambda chunk: _run_chunk(chunk, timeout, memory_mb), chunks):
            outcomes.update(part)
    results = []
    for k, sub in enumerate(submissions):
        res = SubmissionResult(str(sub), sub.resolve().name)
        for ex in exercises:
            missing = sources[(k, ex.name)]
            if missing:
                res.exercises.append(_score(ex, {}, [missing], missing))
                continue
            entry, why = outcomes[f"{k}:{ex.name}"]
            if not isinstance(entry, dict):
                res.exercises.append(_score(ex, {}, [why], why))
                continue
            outcome = entry.get("results") if isinstance(entry.get("results"), dict) else {}
            errors = [str(e)[:300] for e in entry.get("errors", [])][:10]
            res.exercises.append(_score(ex, outcome, errors, "not run"))
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
