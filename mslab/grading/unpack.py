"""A submitted ``.zip``, unpacked inside a sandbox's limits, read back as plain data.

The grader never decompresses a student's zip itself. It reads the zip's bytes once
(:func:`mslab.grading.intake.read_zip`: no link followed, a regular file, at most
``MAX_ZIP`` bytes), then runs the unpacker (:mod:`mslab.grading.unzip`) as a sandbox of
its own: the same isolation as the grading (bubblewrap, the namespace jail, or resource
limits, as a fresh uid when the grader is root), a resource box of its own (cgroup or
/proc meter) and the limits of one test: ``--timeout`` seconds of CPU time for the whole
box (wall-clock backstop as for tests), ``--memory`` MB, files of at most one MB. Its only
writable place besides its private ``/tmp`` is a fresh folder of the grader's (``/out``
inside the namespaces), which the grader reads back once the box is dead
(:func:`mslab.grading.intake.read_tree`: regular files only, no link followed, names and
sizes checked by the unpacker's own rules) and then removes, whatever happened.

Every failure is a reason for the gradebook: a limit the runner's clock, the box or the
exit status showed (decided here), or a refusal of the unpacker's (a fixed phrase per
kind, the member's name quoted as the student's text).
"""

from __future__ import annotations

import json
import os
import secrets
import selectors
import shutil
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from mslab.grading import isolation
from mslab.grading.box import POLL_CGROUP, POLL_PROC, Box, Budget, wall_backstop
from mslab.grading.intake import read_tree, read_zip
from mslab.grading.remote import _exit_reason, _limits, _plan
from mslab.grading.report import printable
from mslab.grading.unzip import REFUSALS

#: bytes of the unpacker's verdict line the grader reads at most
MAX_VERDICT = 4096
#: the name of the zip and of the output folder inside the namespaces
INNER_ZIP, INNER_OUT = "submission.zip", "/out"


@dataclass
class Limits:
    """Where and how a zip is unpacked.

    The grading's isolation ``mode``, its parent ``cgroups`` (or None), the box's
    ``memory_mb``, its CPU seconds ``cpu`` and the grader's own folder ``home``.
    """

    mode: str
    cgroups: dict | None
    memory_mb: int
    cpu: float
    home: Path


def _command(data: bytes, folder: Path, out: Path, limits: Limits, uid: int | None
             ) -> tuple[list[str], tuple[int, ...], int | None]:
    """Return the unpacker's command line, the descriptors it inherits, and the memory file to close."""
    if limits.mode == "rlimits":  # the zip and the unpacker as read-only copies the sandbox's uid may read
        program = (isolation.HERE / "unzip.py").read_bytes()
        for name, content in ((INNER_ZIP, data), ("unzip.py", program)):
            (folder / name).write_bytes(content)
            os.chmod(folder / name, 0o444)
        python = os.path.realpath(sys.executable)
        return [python, "-I", "-S", str(folder / "unzip.py"), str(folder / INNER_ZIP), str(out)], (), None
    fd = os.memfd_create("submission", os.MFD_CLOEXEC)
    os.write(fd, data)
    os.lseek(fd, 0, os.SEEK_SET)
    base = _plan(problems=False)  # the unpacker needs no problem
    plan = isolation.Plan([*base.mounts, isolation.Mount("rw", INNER_OUT, str(out))], base.python)
    argv = [plan.python, "-I", "-S", "/grader/unzip.py", f"/work/{INNER_ZIP}", INNER_OUT]
    build = isolation.bwrap_command if limits.mode == "bwrap" else isolation.jail_command
    return build(plan, fd, uid, argv, module=INNER_ZIP), (fd,), fd


def _run(argv: list[str], fds: tuple[int, ...], cwd: Path, limits: Limits,
         uid: int | None) -> tuple[bytes, str]:
    """Run the unpacker in a box of its own; return what it printed, or ``b""`` and what ended it."""
    box = Box(limits.cgroups, limits.memory_mb)
    env = {"PATH": "/usr/bin:/bin", "LANG": "C.UTF-8", "HOME": str(cwd), "TMPDIR": str(cwd)}
    if limits.mode != "rlimits":
        env.update(HOME="/tmp", TMPDIR="/tmp")
    rlimit_uid = uid if limits.mode == "rlimits" else None
    cpu_s = int(limits.cpu) + 1
    try:
        proc = subprocess.Popen(argv, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, env=env, start_new_session=True, pass_fds=fds,
                                preexec_fn=_limits(limits.memory_mb, cpu_s, 1, limits.mode, box, rlimit_uid))
    except (OSError, subprocess.SubprocessError) as err:
        box.close()
        return b"", f"the unpacking process could not start ({err})"
    box.started(proc.pid)
    budget, out, why = Budget(box, limits.cpu), b"", ""
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    try:
        while True:
            hit = budget.exceeded()
            if hit:
                why = (f"{limits.cpu:g} s of CPU time" if hit == "cpu"
                       else f"{wall_backstop(limits.cpu):g} s of wall-clock time")
                break
            if not sel.select(timeout=POLL_CGROUP if limits.cgroups else POLL_PROC):
                continue
            chunk = os.read(proc.stdout.fileno(), MAX_VERDICT)
            if not chunk or len(out) > MAX_VERDICT:
                break
            out += chunk
        code = proc.wait(timeout=wall_backstop(limits.cpu)) if not why else None
    except subprocess.TimeoutExpired:
        code, why = None, f"{wall_backstop(limits.cpu):g} s of wall-clock time"
    finally:
        sel.close()
        _kill(proc, box, uid if limits.mode == "rlimits" else None)
        oom = box.oom_kills()
        box.close()
    if why:
        return b"", f"unpacking timed out ({why}, the sandbox's limit)"
    if oom:
        return b"", f"ran out of memory while unpacking (the sandbox's limit of {limits.memory_mb} MB)"
    if code in (-signal.SIGXCPU, 128 + signal.SIGXCPU):
        return b"", f"unpacking timed out ({cpu_s} s of CPU time, the sandbox's limit)"
    if code != 0:
        return b"", f"the unpacking process {_exit_reason(code)}"
    return out, ""


def _kill(proc: subprocess.Popen, box: Box, uid: int | None) -> None:
    """Kill the unpacker's session, every process of its box (and of its throwaway uid)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    box.kill()
    proc.stdout.close()
    proc.wait()
    if uid is not None:
        isolation.release_uid(uid)


def _verdict(out: bytes, limits: Limits) -> str:
    """Return why the unpacker refused the zip (its kind's fixed phrase), ``""`` when it unpacked it."""
    try:
        doc = json.loads(out.split(b"\n", 1)[0][:MAX_VERDICT])
    except ValueError:
        return "the unpacking process answered something that is not a verdict"
    if not isinstance(doc, dict) or (doc.get("ok") is not True and doc.get("why") not in REFUSALS):
        return "the unpacking process answered something that is not a verdict"
    if doc.get("ok") is True:
        return ""
    if doc["why"] == "memory":
        return f"ran out of memory while unpacking (the sandbox's limit of {limits.memory_mb} MB)"
    member = printable(str(doc.get("member", "")), 80)
    return REFUSALS[doc["why"]].format(member=repr(member))


def unpack_zip(path: Path, limits: Limits) -> tuple[dict[str, bytes] | None, str]:
    """Return a submitted zip's ``.py`` / ``.ipynb`` files (a common top folder dropped), or None and why.

    The zip is read once; it is unpacked by a sandbox within ``limits`` into a fresh
    folder of ``limits.home`` that is read back as plain data and removed (module docstring).
    """
    data, why = read_zip(path)
    if data is None:
        return None, why
    folder = limits.home / f"unzip-{secrets.token_hex(6)}"
    folder.mkdir(mode=0o711)
    memfd = None
    try:
        out = folder / "out"
        out.mkdir(mode=0o700)
        uid = isolation.new_uid()
        if uid is not None:
            os.chown(out, uid, uid)
        argv, fds, memfd = _command(data, folder, out, limits, uid)
        said, why = _run(argv, fds, out, limits, uid)
        why = why or _verdict(said, limits)
        if why:
            return None, f"{path.name}: {why}"
        files, why = read_tree(out)
        if files is None:
            return None, f"{path.name}: {why}"
    finally:
        if memfd is not None:
            os.close(memfd)
        shutil.rmtree(folder, ignore_errors=True)
    tops = {n.split("/")[0] for n in files}
    if len(tops) == 1 and all("/" in n for n in files):
        files = {n.split("/", 1)[1]: v for n, v in files.items()}
    return files, ""
