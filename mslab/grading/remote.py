"""The runner's handle on the sandbox: start it with limits, talk to it, kill it.

:class:`Student` is what the instructor's tests see as the ``student`` fixture while
grading: ``student.spring_forces(x, ...)`` sends the call to the sandbox and returns the
decoded *data* it answered; errors of the student's code come back as
:class:`StudentError`. A call that does not answer within the test's time limit kills
the sandbox (its whole process group); the next test starts a fresh one.
"""

from __future__ import annotations

import ctypes
import os
import resource
import selectors
import signal
import subprocess
import time
from pathlib import Path

from mslab.grading import isolation
from mslab.grading.wire import WireError, dumps, loads

PR_SET_PDEATHSIG, PR_SET_DUMPABLE, PR_CAPBSET_DROP, PR_SET_NO_NEW_PRIVS = 1, 4, 24, 38
#: processes the student's uid may have at once (namespace modes as root)
MAX_PROCESSES = 64
#: the sandbox's own "type" for an answer it cannot send (no student class has this name)
WIRE_FAILURE = "<wire>"
#: largest single reply accepted from the sandbox (bytes)
MAX_REPLY = 32 * 1024 * 1024


class StudentError(Exception):
    """The student's code failed (raised, timed out, crashed, answered garbage).

    ``mro`` lists the class names of the exception raised in the sandbox (empty when the
    process itself failed), so tests can ask whether the student raised, say, RuntimeError.
    """

    def __init__(self, message: str, mro: tuple[str, ...] = ()):
        super().__init__(message)
        self.mro = tuple(mro)


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


def _limits(memory_mb: int, cpu_s: int, file_mb: int, mode: str = "rlimits"):
    def apply():  # runs in the child between fork and exec
        if mode == "rlimits":
            drop_privileges()
        else:  # bwrap / the jail need their privileges to build the namespaces; they drop them
            try:
                ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
            except (OSError, AttributeError):
                pass
            if os.geteuid() == 0:  # counts the fresh uid's processes only
                resource.setrlimit(resource.RLIMIT_NPROC, (MAX_PROCESSES, MAX_PROCESSES))
        mem = memory_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
        resource.setrlimit(resource.RLIMIT_CPU, (cpu_s, cpu_s + 1))
        size = file_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    return apply


_PLAN: isolation.Plan | None = None


def _plan() -> isolation.Plan:
    global _PLAN
    if _PLAN is None:
        _PLAN = isolation.plan()
    return _PLAN


class Sandbox:
    """One sandbox process running the student's module file ``module_file`` in ``workdir``.

    ``mode`` is the isolation (:mod:`mslab.grading.isolation`). In the namespace modes the
    student's file reaches the sandbox through an anonymous memory file and ``workdir`` is
    not used: the sandbox sees its own ``/work`` only.
    """

    def __init__(self, module_file: Path, workdir: Path, memory_mb: int = 1024, cpu_s: int = 60,
                 file_mb: int = 1, import_timeout: float = 30.0, mode: str = "rlimits"):
        self.module_file = Path(module_file)
        self.mode = mode
        self.import_timeout = float(import_timeout)
        self.workdir = Path(workdir)
        self._source_fd: int | None = None
        if mode != "rlimits":
            self._source_fd = os.memfd_create("student", os.MFD_CLOEXEC)
            os.write(self._source_fd, self.module_file.read_bytes())
        self.memory_mb, self.cpu_s, self.file_mb = memory_mb, cpu_s, file_mb
        self.proc: subprocess.Popen | None = None
        self.broken: str | None = None  # import failed: every later call fails the same way
        self._buf = b""

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
        if self.mode == "rlimits":
            return isolation.rlimit_command(self.module_file), (), self.workdir
        os.lseek(self._source_fd, 0, os.SEEK_SET)
        build = isolation.bwrap_command if self.mode == "bwrap" else isolation.jail_command
        argv = build(_plan(), self._source_fd, isolation.new_uid(), module=self.module_file.name)
        return argv, (self._source_fd,), None

    def ensure_started(self) -> None:
        """Start the sandbox if it is not running (importing the module has its own time limit)."""
        if self.broken:
            raise StudentError(self.broken)
        if self.proc is None or self.proc.poll() is not None:
            self.start(time.monotonic() + self.import_timeout)

    def start(self, deadline: float) -> None:
        """Start the sandbox process; it must have imported the student's file by ``deadline``."""
        argv, fds, cwd = self._command()
        self.proc = subprocess.Popen(
            argv, cwd=cwd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            env=self._env(), start_new_session=True, pass_fds=fds,
            preexec_fn=_limits(self.memory_mb, self.cpu_s, self.file_mb, self.mode))
        self._buf = b""
        hello = self._read(deadline, starting=True)
        if not hello.get("ready"):
            self.broken = str(hello.get("error", "the module could not be imported"))
            self.kill()
            raise StudentError(self.broken)

    def _read(self, deadline: float, starting: bool = False) -> dict:
        sel = selectors.DefaultSelector()
        fd = self.proc.stdout.fileno()
        sel.register(fd, selectors.EVENT_READ)
        try:
            while b"\n" not in self._buf:
                left = deadline - time.monotonic()
                if left <= 0:
                    self.kill()
                    if starting:
                        raise StudentError(f"time limit exceeded: importing the module took over "
                                           f"{self.import_timeout:g} s")
                    raise StudentError("time limit exceeded: the call did not finish in time")
                if not sel.select(timeout=left):
                    continue
                chunk = os.read(fd, 1 << 20)
                if not chunk:
                    code = self.proc.wait(timeout=5)
                    self.kill()
                    when = "while importing the module" if starting else "during the call"
                    reason = _exit_reason(code)
                    if starting:
                        self.broken = f"the process {reason} {when}"
                    raise StudentError(f"the process {reason} {when}")
                self._buf += chunk
                if len(self._buf) > MAX_REPLY:
                    self.kill()
                    raise StudentError(f"the answer is larger than {MAX_REPLY // 2**20} MB")
        finally:
            sel.close()
        line, self._buf = self._buf.split(b"\n", 1)
        try:
            msg = loads(line)
        except WireError as err:
            self.kill()
            raise StudentError(f"the process answered something that is not data ({err})") from None
        if not isinstance(msg, dict):
            self.kill()
            raise StudentError("the process answered something that is not a reply")
        return msg

    def request(self, msg: dict, deadline: float, limit: float | None = None) -> dict:
        """Send one message and return the reply (StudentError when none comes by ``deadline``)."""
        self.ensure_started()
        try:
            self.proc.stdin.write(dumps(msg))
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            self.kill()
            raise StudentError("the process stopped before the call") from None
        try:
            return self._read(deadline)
        except StudentError as err:
            if limit is not None and str(err).startswith("time limit exceeded: the call"):
                raise StudentError(f"time limit exceeded ({limit:g} s per test)") from None
            raise

    def kill(self) -> None:
        """Kill the sandbox process and its whole session."""
        if self.proc is None:
            return
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

    def close(self) -> None:
        """Kill the process and forget the student's file."""
        self.kill()
        if self._source_fd is not None:
            os.close(self._source_fd)
            self._source_fd = None


def _exit_reason(code: int | None) -> str:
    if code is None:
        return "stopped"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        hint = {"SIGXCPU": " (CPU time limit)", "SIGKILL": " (killed)", "SIGXFSZ": " (file size limit)",
                "SIGSEGV": " (crashed, maybe out of memory)"}.get(name, "")
        return f"was stopped by {name}{hint}"
    if 128 < code < 160:  # bwrap reports a signal as 128 + number
        return _exit_reason(128 - code)
    return f"exited with code {code}"


class Student:
    """The student's module as the instructor's tests see it while grading.

    The test's time limit ``timeout`` covers all its calls together; it starts once the
    sandbox is up (importing the module has a limit of its own).
    """

    def __init__(self, sandbox: Sandbox, timeout: float):
        object.__setattr__(self, "_sandbox", sandbox)
        object.__setattr__(self, "_timeout", float(timeout))
        object.__setattr__(self, "_end", None)

    @property
    def _deadline(self) -> float:
        if self._end is None:
            self._sandbox.ensure_started()
            object.__setattr__(self, "_end", time.monotonic() + self._timeout)
        return self._end

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        reply = self._sandbox.request({"op": "getattr", "name": name}, self._deadline, self._timeout)
        if not reply.get("ok"):
            if reply.get("type") == "AttributeError":  # the grader's words, not the student's error
                raise StudentError(_missing(name, reply))
            raise StudentError(_missing(name, reply), _mro(reply))
        if not reply.get("callable"):
            return reply.get("value")

        def call(*args, **kwargs):
            r = self._sandbox.request({"op": "call", "name": name, "args": list(args), "kwargs": kwargs},
                                      self._deadline, self._timeout)
            if not r.get("ok"):
                raise StudentError(f"{name}(): {r.get('error', 'failed')}", _mro(r))
            return r.get("value")

        call.__name__ = name
        return call


def _mro(reply: dict) -> tuple[str, ...]:
    """Return the student's exception classes; none when the sandbox itself reports (data it cannot send)."""
    mro = tuple(str(c) for c in reply.get("mro", ()) if isinstance(c, str))
    return () if mro[:1] == (WIRE_FAILURE,) else mro


def _missing(name: str, reply: dict) -> str:
    if reply.get("type") == "AttributeError":
        return f"missing function '{name}'"
    return f"{name}: {reply.get('error', 'failed')}"
