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

import contextlib
import os
import secrets
import signal
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from mslab.grading.box import describe, wall_backstop
from mslab.grading.box import setup as setup_cgroups
from mslab.grading.box import teardown as teardown_cgroups
from mslab.grading.dispatch import NOT_STARTED, RUNNER_SLACK, STOP, run_runner
from mslab.grading.isolation import DESCRIPTION, detect, unreachable_for_others
from mslab.grading.layout import HIDDEN, Exercise, expand_submissions, find_exercises, read_student_file
from mslab.grading.owner import Owned, clean_abandoned, closed_to_others
from mslab.grading.remote import PHRASES, set_not_dumpable
from mslab.grading.report import Journal, fingerprint, format_report, gradebook_rows, item_key, printable
from mslab.grading.unpack import Limits, unpack_zip

if TYPE_CHECKING:
    from types import FrameType

#: CPU seconds the sandbox may spend importing the student's module (numpy takes about 0.2 s)
IMPORT_CPU = 30.0
#: why a whole item failed when the grader, not the student, failed
GRADER_FAULTS = frozenset({NOT_STARTED})

__all__ = ["ExerciseResult", "SubmissionResult", "TestResult", "format_report", "grade", "gradebook_rows"]

@dataclass
class TestResult:
    """The outcome of one test: points earned of ``max_points``, and why it failed."""

    test: str
    points: float
    max_points: float
    passed: bool
    reason: str
    #: failed for a reason of the grader's own (decided by the runner or the grader, never the sandbox)
    grader_fault: bool = False


@dataclass
class ExerciseResult:
    """The tests of one exercise of one submission, and the errors that kept tests from running."""

    name: str
    tests: list[TestResult] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    @property
    def total(self) -> float:
        """Points earned over all tests."""
        return float(sum(t.points for t in self.tests))

    @property
    def max_points(self) -> float:
        """Points all tests are worth."""
        return float(sum(t.max_points for t in self.tests))


@dataclass
class SubmissionResult:
    """The graded exercises of one student's submission, and the isolation they ran under."""

    submission: str
    student: str
    exercises: list[ExerciseResult] = field(default_factory=list)
    isolation: str = ""
    resources: str = ""
    isolation_asked: str = "auto"

    @property
    def total(self) -> float:
        """Points earned over all exercises."""
        return float(sum(e.total for e in self.exercises))

    @property
    def max_points(self) -> float:
        """Points all exercises are worth."""
        return float(sum(e.max_points for e in self.exercises))

    def to_dict(self) -> dict:
        """Return the result as plain data (for JSON)."""
        return {
            "student": self.student, "submission": self.submission, "isolation": self.isolation,
            "resources": self.resources,
            "total": self.total, "max": self.max_points,
            "exercises": [{"name": e.name, "total": e.total, "max": e.max_points, "errors": e.errors,
                           "tests": [{"test": t.test, "points": t.points, "max": t.max_points,
                                      "passed": t.passed, "reason": t.reason} for t in e.tests]}
                          for e in self.exercises],
        }


@contextlib.contextmanager
def _interrupts():
    """SIGTERM behaves like Ctrl-C while grading: runners are stopped, folders removed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: FrameType | None):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _reason(test: str, entry: dict) -> str:
    """Return the reason shown for a failed test; for a hidden test, its kind's fixed phrase only.

    The runner already sends a hidden test's phrase only; the grader rebuilds it from the
    kind anyway, so no text of the runner's reaches a hidden test's line either.
    """
    if not HIDDEN.match(test.split("::")[0]):
        return str(entry.get("reason", "failed"))[:300]
    return f"hidden test: {PHRASES.get(str(entry.get('kind')), PHRASES['error'])}"


def _score(exercise: Exercise, outcome: dict, errors: list[str], reason_all: str) -> ExerciseResult:
    """Points of one exercise from the runner's outcomes; the test list is the grader's own."""
    result = ExerciseResult(exercise.name, errors=errors)
    for test, max_points in exercise.points.items():
        entry = outcome.get(test) if isinstance(outcome.get(test), dict) else None
        passed = bool(entry and entry.get("passed") is True and not errors)
        if passed:
            reason = "ok"
        elif entry and not errors:
            reason = _reason(test, entry)
        else:
            reason = errors[0] if errors else reason_all
        fault = bool(entry and entry.get("kind") == "grader") or (not entry and reason_all in GRADER_FAULTS)
        result.tests.append(TestResult(test, max_points if passed else 0.0, max_points, passed, reason,
                                       grader_fault=fault and not passed))
    return result


def grader_faults(results: Iterable[SubmissionResult]) -> list[str]:
    """Return ``student: test: reason`` of every test that failed for a reason of the grader's own."""
    return [f"{r.student}: {t.test}: {t.reason}" for r in results for e in r.exercises for t in e.tests
            if t.grader_fault]


def _run_items(items: list[dict], ctx: dict, on_item: Callable[[str, dict], None]) -> tuple[set, str, str]:
    """Run items in one runner: ``(keys finished, why some are missing, the item that overran)``.

    ``ctx``: ``timeout``, ``memory_mb``, ``mode`` (isolation), ``cgroups`` and ``home``
    (the grading's own folder, where the runner's folder is made).
    """
    timeout = ctx["timeout"]
    job = {"nonce": secrets.token_hex(16), "timeout": timeout, "memory_mb": ctx["memory_mb"],
           "isolation": ctx["mode"], "import_timeout": IMPORT_CPU, "cgroups": ctx["cgroups"],
           "home": ctx["home"], "items": items}
    walls = [wall_backstop(timeout) * (it["n_tests"] + 1) + wall_backstop(IMPORT_CPU) + RUNNER_SLACK
             for it in items]
    return run_runner(job, walls, on_item)


def _run_chunk(items: list[dict], ctx: dict, on_item: Callable[[str, dict | None, str], None]) -> None:
    """Run a chunk of items; ``on_item(key, outcome or None, why)`` for each.

    The runner grades items in order and reports each as it finishes. An item that
    overruns its own wall-clock budget is reported so (not re-run: a sleeping sandbox costs
    its own budget once, never its classmates'). If the runner dies, the first unfinished
    item is the suspect: it is re-run alone, and the items after it get a fresh runner, so
    one submission can never cost another one points.
    """
    pending = list(items)
    while pending and not STOP.is_set():
        done, why, overran = _run_items(pending, ctx, lambda k, o: on_item(k, o, ""))
        rest = [it for it in pending if it["key"] not in done]
        if not rest or STOP.is_set():
            break
        if overran:
            on_item(overran, None, why)
            pending = [it for it in rest if it["key"] != overran]
            continue
        suspect = rest[0]
        if len(pending) == 1:  # it already ran alone
            on_item(suspect["key"], None, why or "not graded")
            break
        alone, why_alone, _ = _run_items([suspect], ctx, lambda k, o: on_item(k, o, ""))
        if suspect["key"] not in alone:
            on_item(suspect["key"], None, why_alone or "not graded")
        pending = rest[1:]


def parallel_jobs(jobs: int, mode: str, cgroups: object, euid: int) -> int:
    """How many students are graded at once: ``jobs``, or 1 in rlimits mode.

    rlimits sandboxes share the machine's ``/tmp``, ``/var/tmp`` and ``/dev/shm``: two students
    graded at once could pass files there while both run (a hidden sandbox's inputs to a
    classmate's public message). Graded one at a time, each sandbox's files are removed when it
    ends (as root, :func:`mslab.grading.isolation.release_uid`) before the next one starts. Without
    root every sandbox also runs as the grader's own uid, whose ``RLIMIT_NPROC`` counts all of
    its processes: a fork bomb would starve a classmate's sandbox running beside it.
    ``cgroups`` and ``euid`` are kept for the callers; rlimits means one at a time either way.
    """
    del cgroups, euid
    return 1 if mode == "rlimits" else jobs


def grade(paths: Iterable[str | Path], source: str | Path, jobs: int | None = None, timeout: float = 10.0,
          memory_mb: int = 1024, only: list[str] | None = None, isolation: str = "auto",
          require_isolation: bool = False, journal: str | Path | Journal | None = None, resume: bool = False,
          progress: Callable[[int, int], None] | None = None, layout: str = "auto",
          ignore: Iterable[str | Path] = ()) -> list[SubmissionResult]:
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
        CPU seconds per test (the student's calls of one test together, every process of
        the sandbox counted), with a wall-clock backstop (``box.wall_backstop``).
    only : list of str, optional
        Grade only these exercise folders.
    isolation : {"auto", "bwrap", "namespaces", "rlimits"}
        How student code is isolated (:mod:`mslab.grading.isolation`); ``auto``: the strongest.
    require_isolation : bool
        Refuse (ValueError) rather than grade without namespaces or without a cgroup per
        sandbox (:mod:`mslab.grading.box`).
    journal : path or Journal, optional
        Append each item's outcome here as it arrives (locked while grading: one grader
        per journal). The file stays for the caller to remove once its gradebook is
        written; an open :class:`Journal` stays locked until its caller closes it.
    resume : bool
        Reuse the outcomes already in ``journal`` (same tests, limits and student files).
    progress : callable, optional
        ``progress(done, total)`` after each item.
    layout : {"auto", "class", "submission"}
        How a path is read: one submission or a class (:mod:`mslab.grading.intake`).
    ignore : list of path
        Files of a class folder that are not students' (the gradebook being written).
    """
    set_not_dumpable()  # no process of ours may read the nonces from our memory
    mode = detect(isolation)
    if require_isolation and mode == "rlimits":
        why = ("--isolation rlimits was chosen" if isolation == "rlimits"
               else "this machine offers no namespaces (no bwrap, no user namespaces)")
        raise ValueError(f"isolation required, but {why}: grading would run student code without namespaces")
    if mode == "rlimits" and os.geteuid() == 0 and (where := unreachable_for_others()):
        raise ValueError(f"isolation rlimits as root runs student code as a throwaway user, who cannot "
                         f"reach {where}: install Python and numpy where other users can run them")
    jobs = max(1, jobs or os.cpu_count() or 1)
    book = journal if isinstance(journal, Journal) or journal is None else Journal(journal, resume)
    owned = Owned()
    cgroups = None
    try:
        cgroups, why_not = setup_cgroups(jobs, owned.name)
        if require_isolation and cgroups is None:
            raise ValueError(f"isolation required, but no cgroup can cap each sandbox's processes, memory "
                             f"and CPU share here ({why_not})")
        jobs = parallel_jobs(jobs, mode, cgroups, os.geteuid())
        ctx = {"timeout": timeout, "memory_mb": memory_mb, "mode": mode, "cgroups": cgroups,
               "home": str(owned.folder), "asked": isolation, "why_not": why_not}
        paths = list(paths)
        guarded = [source, *paths] if mode == "rlimits" and os.geteuid() == 0 else []
        with closed_to_others(guarded):
            return _grade(paths, source, jobs, only, ctx, book, progress, (layout, ignore))
    finally:
        teardown_cgroups(cgroups)
        owned.close()
        if book is not None and book is not journal:
            book.close(finished=False)  # released; the caller removes it once the gradebook is written


def _grade(paths: Iterable[str | Path], source: str | Path, jobs: int, only: list[str] | None, ctx: dict,
           book: Journal | None, progress: Callable[[int, int], None] | None,
           intake: tuple[str, Iterable]) -> list[SubmissionResult]:
    timeout, memory_mb, mode, cgroups = ctx["timeout"], ctx["memory_mb"], ctx["mode"], ctx["cgroups"]
    exercises = find_exercises(source)
    if only:
        unknown = set(only) - {e.name for e in exercises}
        if unknown:
            raise ValueError(f"unknown exercise(s): {', '.join(sorted(unknown))}")
        exercises = [e for e in exercises if e.name in only]
    submissions = expand_submissions(paths, exercises, *intake)
    clean_abandoned()
    unzip_limits = Limits(mode, cgroups, memory_mb, timeout, Path(ctx["home"]))
    for sub in submissions:  # each zip unpacked once, by a sandbox within one test's limits
        if sub.kind == "zip" and not sub.refusal:
            sub.files, sub.refusal = unpack_zip(sub.path, unzip_limits)
    if book is not None:
        book.bind(fingerprint(exercises, timeout, memory_mb))
    outcomes: dict[str, tuple] = {}
    fixed: dict[tuple, str] = {}
    items, keys = [], {}
    for k, sub in enumerate(submissions):  # every student file read once, here: the snapshot graded
        for ex in exercises:
            text, why = read_student_file(sub, ex)
            if text is None:
                fixed[(k, ex.name)] = why
                continue
            key = item_key(sub.path, ex.name, text)
            keys[(k, ex.name)] = key
            if key in outcomes or any(it["key"] == key for it in items):
                continue  # the same folder twice on the command line
            if book is not None and isinstance(book.done.get(key), dict):
                outcomes[key] = (book.done[key].get("entry"), str(book.done[key].get("why", "")))
                continue
            items.append({"key": key, "name": ex.name, "module": ex.module, "student_source": text,
                          "tests": ex.tests, "n_tests": len(ex.points), "problems": ex.hands_problems,
                          "cpu_s": int(timeout * len(ex.points) + 60)})
    lock = threading.Lock()
    total = len(items)

    def on_item(key: str, entry: dict | None, why: str) -> None:
        with lock:
            if key in outcomes:
                return
            outcomes[key] = (entry, why)
            if book is not None:
                book.add(key, {"entry": entry, "why": why})
            if progress is not None:
                progress(sum(it["key"] in outcomes for it in items), total)

    chunks = [items[j::jobs] for j in range(jobs) if items[j::jobs]]
    STOP.clear()
    with _interrupts(), ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = [pool.submit(_run_chunk, chunk, ctx, on_item)
                   for chunk in chunks]
        try:
            for f in futures:
                f.result()
        except BaseException:
            STOP.set()
            raise
    results = []
    boxed = describe(cgroups, memory_mb) + ("" if cgroups else f" ({ctx['why_not']})")
    for k, sub in enumerate(submissions):
        res = SubmissionResult(str(sub.path), printable(sub.name), isolation=DESCRIPTION[mode],
                               resources=boxed, isolation_asked=ctx["asked"])
        for ex in exercises:
            if (k, ex.name) in fixed:
                why = fixed[(k, ex.name)]
                res.exercises.append(_score(ex, {}, [why], why))
                continue
            entry, why = outcomes.get(keys[(k, ex.name)], (None, "not graded"))
            if not isinstance(entry, dict):
                res.exercises.append(_score(ex, {}, [why or "not graded"], why or "not graded"))
                continue
            outcome = entry.get("results") if isinstance(entry.get("results"), dict) else {}
            errors = [str(e)[:300] for e in entry.get("errors", [])][:10]
            res.exercises.append(_score(ex, outcome, errors, "not run"))
        results.append(res)
    return results
