"""The test runner: runs the instructor's tests for one exercise of one submission.

Started by the grader as ``python -E -s -P -m mslab.grading.runner`` with a JSON job on
stdin: a random nonce, limits, and a list of items, each one exercise of one submission
(the instructor's test sources and the student's file). One runner grades many items in
turn, so the interpreter, pytest and mslab are imported once. It is *trusted*:
student code never runs in this process. It

1. makes itself non-dumpable (``prctl(PR_SET_DUMPABLE, 0)``), so processes of the same
   user without capabilities (the sandbox) cannot open its ``/proc/PID/fd`` or memory,
   says ``ready`` (only then does the grader send the job), keeps a private copy of stdout
   for the result and points its standard streams at ``/dev/null``;
2. writes the tests into a fresh temporary folder and the student's source (as the grader
   sent it: the runner reads no student path) into one folder per test group;
3. runs pytest in-process on the tests (no conftest, no plugin autoload, importlib
   import mode) with :class:`GradingPlugin`, whose ``student`` fixture forwards every call
   to the sandbox (:mod:`mslab.grading.remote`) of the test's group: hidden and public
   tests never share a sandbox process; the tests' own assertions run here, on answers
   decoded as plain data (:mod:`mslab.grading.wire`), each test's under a CPU limit of
   the runner's own (:func:`check_cpu_limit`);
4. checks the test files still hold what the grader sent (else the run counts as
   tampered) and prints one line ``NONCE JSON`` per item with every test's outcome.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import sys
import tempfile
from collections.abc import Callable, Generator, Iterator
from pathlib import Path

import pytest

from mslab.grading import reaper
from mslab.grading.layout import HIDDEN
from mslab.grading.remote import PHRASES, Sandbox, Student, StudentError, set_not_dumpable


def short_reason(excinfo: pytest.ExceptionInfo, hidden: bool) -> tuple[str, str]:
    """Return the line for the grade report and the kind of failure (a key of ``PHRASES``).

    Kinds: those of :class:`StudentError` (decided by the runner, see
    :mod:`mslab.grading.remote`), ``wrong`` (an assertion of the test failed), ``error``
    (the test itself failed otherwise). A hidden test's line is the kind's fixed phrase:
    neither the test's own values nor anything the sandbox said.
    """
    err = excinfo.value
    if isinstance(err, StudentError):
        text, kind = str(err), err.kind
    elif isinstance(err, AssertionError):
        text = str(err).strip().splitlines()[0] if str(err).strip() else "assertion failed"
        kind = "wrong"
    else:
        first = str(err).splitlines()[0] if str(err) else ""
        text = f"{type(err).__name__}: {first}" if first else type(err).__name__
        kind = "error"
    return (PHRASES[kind] if hidden else text[:300]), kind


#: the runner's own CPU seconds per test (the instructor's checks on the answers) are at most
#: CHECK_CPU_FACTOR times the test's limit, and at least CHECK_CPU_MIN: honest checks take seconds
CHECK_CPU_FACTOR, CHECK_CPU_MIN = 6.0, 60.0


def check_cpu_limit(timeout: float) -> float:
    """Return the CPU seconds the runner may spend on one test's own checks."""
    return max(CHECK_CPU_MIN, CHECK_CPU_FACTOR * float(timeout))


def test_group(filename: str) -> str:
    """``"hidden"`` or ``"public"``: the tests of one group share a sandbox, never two groups."""
    return "hidden" if HIDDEN.match(filename) else "public"


class GradingPlugin:
    """pytest plugin of the runner: the ``student`` fixture and the outcome of every test.

    ``make_sandbox(group)`` starts the student's module afresh for a test group. Hidden and
    public tests never share a sandbox: when a test of the other group asks for the
    student, every sandbox of the group before is closed (its processes killed, its box
    removed) and a new one is made, so nothing computed from a hidden input can reach a
    public test's message.
    """

    def __init__(self, make_sandbox: Callable[[str], Sandbox] | None, timeout: float,
                 missing: str | None = None, check_cpu: float | None = None):
        self.make_sandbox = make_sandbox
        self.check_cpu = check_cpu_limit(timeout) if check_cpu is None else float(check_cpu)
        self.sandboxes: dict[str, Sandbox] = {}
        self.timeout = float(timeout)
        self.missing = missing
        self.results: dict[str, dict] = {}
        self.collect_errors: list[str] = []
        self.tamper_check = None

    def sandbox(self, group: str) -> Sandbox:
        """Return the sandbox of ``group``, closing every other group's first."""
        for other in [g for g in self.sandboxes if g != group]:
            self.sandboxes.pop(other).close()
            reaper.kill_orphans()
        if group not in self.sandboxes:
            self.sandboxes[group] = self.make_sandbox(group)
        return self.sandboxes[group]

    def close(self) -> None:
        """Close every sandbox (and kill what its processes left, :func:`reaper.kill_orphans`)."""
        while self.sandboxes:
            self.sandboxes.popitem()[1].close()
        reaper.kill_orphans()

    @pytest.fixture
    def student(self, request: pytest.FixtureRequest) -> Student:
        """Fixture: the student's module, each call forwarded to the sandbox of the test's group."""
        if self.missing:
            raise StudentError(self.missing, "missing")
        return Student(self.sandbox(test_group(Path(str(request.node.fspath)).name)), self.timeout)

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_call(self, item: pytest.Item) -> Generator[None, None, None]:
        """Run the test body under the runner's own CPU limit (``ITIMER_PROF``: this process only).

        Whatever the checks do with the student's answers, one test costs the runner at most
        :attr:`check_cpu` CPU seconds; the test then fails as a CPU timeout.
        """
        def expired(signum: int, frame: object) -> None:
            raise StudentError(f"the checks of this answer exceeded {self.check_cpu:g} s of the "
                               f"grader's CPU time", "cpu")

        previous = signal.signal(signal.SIGPROF, expired)
        signal.setitimer(signal.ITIMER_PROF, self.check_cpu)
        try:
            return (yield)
        finally:
            signal.setitimer(signal.ITIMER_PROF, 0)
            signal.signal(signal.SIGPROF, previous)

    def pytest_collection_modifyitems(self, items: list[pytest.Item]) -> None:
        """Run the public tests first, the hidden ones after (each group in file order).

        Separate sandboxes keep a hidden input out of a public sandbox's memory; where
        sandboxes share a writable folder (``rlimits`` mode: ``/tmp``, ``/dev/shm``), only this
        order keeps it out of a public test's message: every public message is written
        before the first hidden input exists.
        """
        items.sort(key=lambda item: test_group(Path(str(item.fspath)).name) == "hidden")

    def pytest_collectreport(self, report: pytest.CollectReport) -> None:
        """Record a test file that could not be collected."""
        if report.failed:
            self.collect_errors.append(f"{report.nodeid}: {str(report.longrepr).splitlines()[-1][:200]}")

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        """Skip every test when the test files changed on disk (tampering)."""
        if self.tamper_check is not None and not self.tamper_check():
            self.collect_errors.append("the test files changed on disk during grading (tampering)")
            session.shouldstop = "tampered"
            for item in session.items:
                item.add_marker(pytest.mark.skip(reason="tampered"))

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_makereport(
        self, item: pytest.Item, call: pytest.CallInfo
    ) -> Generator[None, pytest.TestReport, pytest.TestReport]:
        """Record each test's outcome and, for a failure, its reason."""
        rep = yield
        key = f"{Path(item.fspath).name}::{item.name}"
        entry = self.results.setdefault(key, {"passed": None, "reason": "not run"})
        if rep.failed:
            entry["passed"] = False
            if call.excinfo:
                hidden = bool(HIDDEN.match(Path(item.fspath).name))
                entry["reason"], entry["kind"] = short_reason(call.excinfo, hidden)
            else:
                entry["reason"], entry["kind"] = "failed", "error"
        elif rep.skipped:
            entry["passed"] = False
            entry["reason"] = "skipped"
        elif rep.when == "call" and entry["passed"] is None:
            entry["passed"] = True
            entry["reason"] = "ok"
        return rep


def run_exercise(job: dict, ex: dict) -> dict:
    """Run the tests of one exercise on one student's file; the outcome as a dict."""
    root = Path(tempfile.mkdtemp(prefix="item-", dir=job.get("tmp")))
    tests_dir, work_dir = root / "tests", root / "work"
    tests_dir.mkdir()
    work_dir.mkdir()
    try:
        for name, text in ex["tests"].items():
            (tests_dir / name).write_text(text)
            os.chmod(tests_dir / name, 0o444)
        ini = tests_dir / "pytest.ini"
        ini.write_text("[pytest]\nmarkers =\n    points(n): points a test is worth\n")
        os.chmod(tests_dir, 0o555)
        missing = None
        if ex.get("student_source") is None:
            missing = f"{ex['module']} is missing from the submission"
        source = (ex.get("student_source") or "").encode()

        def make_sandbox(group: str) -> Sandbox:
            # the source as the grader sent it (no student path is read here); a folder per group
            folder = work_dir / group
            folder.mkdir()
            (folder / ex["module"]).write_bytes(source)
            return Sandbox(folder / ex["module"], folder, memory_mb=int(job.get("memory_mb", 1024)),
                           cpu_s=int(ex.get("cpu_s", 120)),
                           import_timeout=float(job.get("import_timeout", 30.0)),
                           mode=job.get("isolation", "rlimits"), cgroups=job.get("cgroups"), source=source,
                           problems=bool(ex.get("problems", True)))

        plugin = GradingPlugin(make_sandbox, float(job.get("timeout", 10.0)), missing,
                               check_cpu=job.get("check_cpu"))

        def unchanged() -> bool:
            files = {p.name for p in tests_dir.iterdir()} - {"__pycache__"}
            if files != set(ex["tests"]) | {"pytest.ini"}:
                return False
            return all((tests_dir / n).read_text() == t for n, t in ex["tests"].items())

        plugin.tamper_check = unchanged
        # tests in file order (never shuffled by a plugin: a test group shares one sandbox)
        args = [str(tests_dir), "-q", "-c", str(ini), "--rootdir", str(tests_dir), "--noconftest",
                "--confcutdir", str(tests_dir), "--import-mode=importlib", "-p", "no:cacheprovider",
                "-p", "no:randomly",
                "-o", "python_files=test_*.py", "-o", "addopts=", "-o", "console_output_style=classic"]
        try:
            pytest.main(args, plugins=[plugin])
        finally:
            plugin.close()
            # importlib mode caches test modules by name: forget them for the next exercise
            for key, module in list(sys.modules.items()):
                if str(getattr(module, "__file__", None) or "").startswith(str(tests_dir)):
                    del sys.modules[key]
        return {"results": plugin.results, "errors": plugin.collect_errors}
    finally:
        for folder in (tests_dir, root):
            try:
                os.chmod(folder, 0o755)
            except OSError:
                pass
        shutil.rmtree(root, ignore_errors=True)


def run_job(job: dict) -> Iterator[tuple[str, dict]]:
    """Run every item (one exercise of one submission) of the job in turn; yield ``(key, outcome)``."""
    for item in job["items"]:
        try:
            yield item["key"], run_exercise(job, item)
        except Exception as err:  # noqa: BLE001 - this item fails, the next one still runs
            yield item["key"], {"results": {}, "errors": [f"runner failed: {type(err).__name__}: {err}"]}


def main() -> None:
    """Run the job read from stdin; print one ``NONCE JSON`` line per item."""
    set_not_dumpable()
    reaper.become_subreaper()
    sys.dont_write_bytecode = True
    out = os.fdopen(os.dup(1), "w")
    out.write("ready\n")  # only now may the grader send the job (and its nonce)
    out.flush()
    job = json.loads(sys.stdin.read())
    devnull = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        os.dup2(devnull, fd)
    for key, outcome in run_job(job):  # one line per item: a crash loses only what is left
        out.write(job["nonce"] + " " + json.dumps({"key": key, "outcome": outcome}) + "\n")
        out.flush()


if __name__ == "__main__":
    main()
