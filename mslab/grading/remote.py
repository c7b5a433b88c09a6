"""The runner's handle on the sandbox: start it with limits, talk to it, kill it.

:class:`Student` is what the instructor's tests see as the ``student`` fixture while
grading: ``student.spring_forces(x, ...)`` sends the call to the sandbox and returns the
decoded *data* it answered; every failure comes back as :class:`StudentError` whose kind
the runner decided from what it saw itself, never from the sandbox's words. A test's limit
is CPU time of the whole sandbox (cgroup, else process tree in /proc) with a generous wall-clock
backstop; hitting either kills the sandbox (box and process group); the next test starts afresh.
"""

from __future__ import annotations

import ctypes
import os
import resource
import selectors
import signal
import subprocess
from pathlib import Path

from mslab.grading import isolation
from mslab.grading.box import (
    MAX_PROCESSES,
    POLL_CGROUP,
    POLL_PROC,
    Box,
    Budget,
    user_process_cap,
    wall_backstop,
)
from mslab.grading.wire import WireError, dumps, loads

PR_SET_PDEATHSIG, PR_SET_DUMPABLE, PR_CAPBSET_DROP, PR_SET_NO_NEW_PRIVS = 1, 4, 24, 38
#: largest single reply accepted from the sandbox (bytes)
MAX_REPLY = 32 * 1024 * 1024
#: characters of the student's own text (an exception's message) a public test may show
STUDENT_TEXT = 200
#: the runner's words for each kind of failure: all a hidden test ever shows (no sandbox text)
PHRASES = {
    "wrong": "wrong value",
    "raised": "raised an exception",
    "not_data": "answered something that is not plain data",
    "missing": "missing function",
    "import": "the module could not be imported",
    "cpu": "timed out (CPU time limit)",
    "wall": "timed out (wall-clock limit)",
    "memory": "ran out of memory",
    "died": "the process died",
    "error": "failed",
    "grader": "the grader failed (not the student's fault)",
}


class StudentError(Exception):
    """The student's code failed (raised, timed out, crashed, answered garbage).

    ``kind`` (a key of :data:`PHRASES`) is the runner's own classification: from what it
    saw itself (its clock, the sandbox's CPU time and exit status, its own decoding), or,
    for ``raised``, ``not_data``, ``missing`` and ``import``, from the *fact* that the
    sandbox answered so; the sandbox's words are never read for the kind. The message may
    quote the student's text (public tests only show it). ``mro`` lists the class names
    the sandbox claims for the exception (the student's claim, used only by
    :func:`mslab.grading.checks.raised`).
    """

    def __init__(self, message: str, kind: str = "error", mro: tuple[str, ...] = ()):
        super().__init__(message)
        self.kind = kind if kind in PHRASES else "error"
        self.mro = tuple(mro)


def student_text(value: object) -> str:
    """Return the student's own text: one line, bounded to :data:`STUDENT_TEXT` characters."""
    text = " ".join(str(value).split())
    return text if len(text) <= STUDENT_TEXT else text[: STUDENT_TEXT - 3] + "..."


def drop_privileges() -> None:
    """No new privileges, and no capabilities even for root (Linux; elsewhere a no-op).

    A capability-less process can open ``/proc/PID/fd`` or ``mem`` of another process of
    the same user only if that one is dumpable; the runner and the grader are not.
    """
    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError:
        return
    prctl = getattr(libc, "prctl", None)
    if prctl is None:
        return
    prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0)
    if os.geteuid() == 0:
        for cap in range(64):  # empty bounding set: exec gives root no capabilities
            prctl(PR_CAPBSET_DROP, cap, 0, 0, 0)


def set_not_dumpable() -> None:
    """``prctl(PR_SET_DUMPABLE, 0)``: other processes of this user cannot read our /proc entries."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_DUMPABLE, 0, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _limits(memory_mb: int, cpu_s: int, file_mb: int, mode: str = "rlimits", box: Box | None = None,
            uid: int | None = None):
    def apply():  # runs in the child between fork and exec
        if box is not None:
            box.enter()  # before anything of the student's runs: every process it starts stays in
        if mode == "rlimits":
            if uid is not None:  # root: a throwaway uid, whose processes are the sandbox's only
                resource.setrlimit(resource.RLIMIT_NPROC, (MAX_PROCESSES, MAX_PROCESSES))
                isolation.become(uid)
            drop_privileges()
        else:  # bwrap / the jail need their privileges to build the namespaces; they drop them
            try:
                ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
            except (OSError, AttributeError):
                pass
            if os.geteuid() == 0:  # counts the fresh uid's processes only
                resource.setrlimit(resource.RLIMIT_NPROC, (MAX_PROCESSES, MAX_PROCESSES))
        if uid is None and os.geteuid() != 0 and (box is None or not box.config):  # no cgroup: cap the count
            cap = user_process_cap(MAX_PROCESSES)
            resource.setrlimit(resource.RLIMIT_NPROC, (cap, cap))
        mem = memory_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
        resource.setrlimit(resource.RLIMIT_CPU, (cpu_s, cpu_s + 1))
        size = file_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    return apply


_PLANS: dict[bool, isolation.Plan] = {}


def _plan(problems: bool = True) -> isolation.Plan:
    if problems not in _PLANS:
        _PLANS[problems] = isolation.plan(problems)
    return _PLANS[problems]


class Sandbox:
    """One sandbox process running the student's module file ``module_file`` in ``workdir``.

    ``mode`` is the isolation (:mod:`mslab.grading.isolation`). In the namespace modes the
    student's file reaches the sandbox through an anonymous memory file and ``workdir`` is
    not used: the sandbox sees its own ``/work`` only. ``source``: the module's bytes as the
    runner received them (then no file is read again). ``cgroups`` is the grading's parent
    cgroup (:func:`mslab.grading.box.setup`) or None: each start gets a fresh :class:`Box`.
    ``problems=False``: the sandbox gets no ``problems.py`` (an exercise whose tests hand the
    student no problem: that file's spring forces are exercise 01's answer).
    """

    def __init__(self, module_file: Path, workdir: Path, memory_mb: int = 1024, cpu_s: int = 60,
                 file_mb: int = 1, import_timeout: float = 30.0, mode: str = "rlimits",
                 cgroups: dict | None = None, source: bytes | None = None, problems: bool = True):
        self.module_file = Path(module_file)
        self.problems = problems
        self.mode = mode
        self.import_timeout = float(import_timeout)
        self.workdir = Path(workdir)
        self.cgroups = cgroups
        self._source_fd: int | None = None
        if mode != "rlimits":
            self._source_fd = os.memfd_create("student", os.MFD_CLOEXEC)
            data = self.module_file.read_bytes() if source is None else source
            os.write(self._source_fd, data)
        self.memory_mb, self.cpu_s, self.file_mb = memory_mb, cpu_s, file_mb
        self.proc: subprocess.Popen | None = None
        self.box: Box | None = None
        self.broken: StudentError | None = None  # import failed: every later call fails the same way
        self._buf = b""
        self.uid: int | None = None  # rlimits as root: the sandbox's throwaway uid

    def _env(self) -> dict:
        keep = ("PATH", "LANG", "LC_ALL", "SYSTEMROOT")
        env = {k: os.environ[k] for k in keep if k in os.environ}
        env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1",
                   PYTHONDONTWRITEBYTECODE="1", PYTHONHASHSEED="0", HOME=str(self.workdir),
                   TMPDIR=str(self.workdir), MPLBACKEND="Agg")
        if self.mode != "rlimits":
            env.update(HOME="/work", TMPDIR="/tmp", PATH="/usr/bin:/bin")
        return env

    def _command(self) -> tuple[list[str], tuple[int, ...], Path | None]:
        if self.mode == "rlimits":  # as root: a throwaway uid on a stage of its own
            argv, cwd, self.uid = isolation.rlimits_sandbox(self.module_file, self.workdir, self.problems)
            return argv, (), cwd
        os.lseek(self._source_fd, 0, os.SEEK_SET)
        build = isolation.bwrap_command if self.mode == "bwrap" else isolation.jail_command
        argv = build(_plan(self.problems), self._source_fd, isolation.new_uid(), module=self.module_file.name)
        return argv, (self._source_fd,), None

    def ensure_started(self) -> None:
        """Start the sandbox if it is not running (importing the module has its own limits)."""
        if self.broken:
            raise self.broken
        if self.proc is None or self.proc.poll() is not None:
            self.start()

    def start(self) -> None:
        """Start the sandbox process in a fresh box; it must import the student's file within its limits."""
        self.kill()
        argv, fds, cwd = self._command()
        self.box = Box(self.cgroups, self.memory_mb)
        env = self._env() if self.uid is None else dict(self._env(), HOME=str(cwd), TMPDIR=str(cwd))
        try:
            self.proc = subprocess.Popen(
                argv, cwd=cwd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                env=env, start_new_session=True, pass_fds=fds,
                preexec_fn=_limits(self.memory_mb, self.cpu_s, self.file_mb, self.mode, self.box, self.uid))
        except (OSError, subprocess.SubprocessError) as err:  # before any student code: the grader's own
            self.broken = StudentError(f"the grader could not start the sandbox ({type(err).__name__}: "
                                       f"{str(err)[:200]})", "grader")
            raise self.broken from None
        self.box.started(self.proc.pid)
        self._buf = b""
        try:
            hello = self._read(Budget(self.box, self.import_timeout), "while importing the module")
        except StudentError as err:
            self.broken = StudentError(f"the module could not be imported: {err}", err.kind)
            raise self.broken from None
        if not hello.get("ready"):  # the sandbox's words: the student's text
            self.broken = StudentError(f"the module could not be imported: "
                                       f"{student_text(hello.get('error', ''))}", "import")
            self.kill()
            raise self.broken

    def _died(self, when: str) -> StudentError:
        """Return the runner's own account of a process that stopped: exit status, CPU and memory events."""
        try:
            code = self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            code = None
        oom = self.box.oom_kills() if self.box else 0
        self.kill()
        if oom:
            return StudentError(f"ran out of memory {when} (the sandbox's memory limit)", "memory")
        if code in (-signal.SIGXCPU, 128 + signal.SIGXCPU):
            return StudentError(f"timed out {when} (CPU time limit of a process)", "cpu")
        return StudentError(f"the process {_exit_reason(code)} {when}", "died")

    def _read(self, budget: Budget, when: str) -> dict:
        sel = selectors.DefaultSelector()
        fd = self.proc.stdout.fileno()
        sel.register(fd, selectors.EVENT_READ)
        poll = POLL_CGROUP if self.cgroups else POLL_PROC
        try:
            while b"\n" not in self._buf:
                hit = budget.exceeded(every=poll)
                if hit:
                    self.kill()
                    limit = (f"{budget.cpu_limit:g} s of CPU time" if hit == "cpu"
                             else f"{wall_backstop(budget.cpu_limit):g} s of wall-clock time")
                    raise StudentError(f"timed out {when} ({limit})", hit)
                if not sel.select(timeout=poll):
                    continue
                chunk = os.read(fd, 1 << 20)
                if not chunk:
                    raise self._died(when)
                self._buf += chunk
                if len(self._buf) > MAX_REPLY:
                    self.kill()
                    raise StudentError(f"answered more than {MAX_REPLY // 2**20} MB", "not_data")
        finally:
            sel.close()
        line, self._buf = self._buf.split(b"\n", 1)
        try:
            msg = loads(line)
        except WireError:
            self.kill()
            raise StudentError("the process answered something that is not data", "not_data") from None
        if not isinstance(msg, dict):
            self.kill()
            raise StudentError("the process answered something that is not a reply", "not_data")
        return msg

    def request(self, msg: dict, budget: Budget) -> dict:
        """Send one message and return the reply (StudentError when a limit of ``budget`` is hit)."""
        self.ensure_started()
        try:
            self.proc.stdin.write(dumps(msg))
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            raise self._died("before the call") from None
        return self._read(budget, "during the call")

    def kill(self) -> None:
        """Kill the sandbox process, its whole session and everything in its box."""
        if self.proc is not None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            for stream in (self.proc.stdin, self.proc.stdout):
                try:
                    stream.close()
                except OSError:
                    pass
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass
            self.proc = None
        if self.uid is not None:
            isolation.release_uid(self.uid)
            self.uid = None
        if self.box is not None:
            self.box.close()
            self.box = None

    def close(self) -> None:
        """Kill the process and forget the student's file."""
        self.kill()
        if self._source_fd is not None:
            os.close(self._source_fd)
            self._source_fd = None


def _exit_reason(code: int | None) -> str:
    if code is None:
        return "did not stop"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        hint = {"SIGKILL": " (killed)", "SIGXFSZ": " (file size limit)",
                "SIGSEGV": " (crashed, maybe out of memory)"}.get(name, "")
        return f"was stopped by {name}{hint}"
    if 128 < code < 160:  # bwrap reports a signal as 128 + number
        return _exit_reason(128 - code)
    return f"exited with code {code}"


class Student:
    """The student's module as the instructor's tests see it while grading.

    The test's limit ``timeout`` is CPU time of the whole sandbox for all its calls
    together, with a wall-clock backstop (:func:`wall_backstop`); it starts once the
    sandbox is up (importing the module has limits of its own). Every failure is a
    :class:`StudentError` of a kind the runner decided; the student's own text appears in
    the message only as a quote (:func:`student_text`).
    """

    def __init__(self, sandbox: Sandbox, timeout: float):
        object.__setattr__(self, "_sandbox", sandbox)
        object.__setattr__(self, "_timeout", float(timeout))
        object.__setattr__(self, "_budget", None)

    def _request(self, msg: dict) -> dict:
        budget = self._budget
        if budget is None or budget.box is not self._sandbox.box or self._sandbox.proc is None:
            self._sandbox.ensure_started()  # a fresh sandbox (after a kill) gets what is left of the limit
            left = self._timeout if budget is None else max(0.0, budget.cpu_limit - budget.spent)
            budget = Budget(self._sandbox.box, left)
            object.__setattr__(self, "_budget", budget)
        return self._sandbox.request(msg, budget)

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        reply = self._request({"op": "getattr", "name": name})
        if not reply.get("ok"):
            if reply.get("type") == "AttributeError":
                raise StudentError(f"missing function '{name}'", "missing")
            raise _student_failure(name, reply)
        if not reply.get("callable"):
            return reply.get("value")

        def call(*args, **kwargs):
            r = self._request({"op": "call", "name": name, "args": list(args), "kwargs": kwargs})
            if not r.get("ok"):
                raise _student_failure(f"{name}()", r)
            return r.get("value")

        call.__name__ = name
        return call


def _student_failure(what: str, reply: dict) -> StudentError:
    """Return a failure the sandbox reported: kind from the reply's shape, words quoted as the student's."""
    text = student_text(reply.get("error", ""))
    mro = tuple(str(c)[:100] for c in reply.get("mro", ()) if isinstance(c, str))[:64]
    if reply.get("unencodable") is True:
        return StudentError(f"{what}: answered something that is not plain data: {text}", "not_data")
    return StudentError(f"{what}: {text}", "raised", mro)
