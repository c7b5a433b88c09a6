"""Runner processes: start one, hand it a job, stream back each item's outcome, clean up.

The runner (:mod:`mslab.grading.runner`) is trusted but its students are not, so the
grader treats it as unreliable: it bounds its memory and output, kills it at a wall-clock
limit, and owns its temporary folder, inside the grading's own folder
(:mod:`mslab.grading.owner`): removed however the runner ended, and a killed grader's
folders by the next grader, never a live one's.
"""

from __future__ import annotations

import ctypes
import json
import os
import resource
import selectors
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

from mslab.grading.isolation import HOME_ENV
from mslab.grading.remote import PR_SET_PDEATHSIG

#: seconds a runner may need beyond its tests' time limits (interpreter, pytest, imports)
RUNNER_SLACK = 60.0
#: the folder holding the grader's own ``mslab`` (the runner imports the same code)
PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])
RUNNER_BOOT = "import sys; sys.path.insert(0, {root!r}); from mslab.grading.runner import main; main()"
#: bytes of runner output the grader reads at most
MAX_RUNNER_OUTPUT = 16 * 1024 * 1024
#: address-space limit of a test runner (MB): it decodes what the sandbox answers; at least the
#: sandbox's own limit, which the runner's children cannot raise above it (:func:`runner_memory_mb`)
RUNNER_MEMORY_MB = 4096
#: why every item of a runner that never said ``ready`` failed: the grader's fault, not a student's
NOT_STARTED = "the test runner did not start"
#: set when grading is interrupted: every runner is stopped and its folder removed
STOP = threading.Event()


def runner_memory_mb(sandbox_mb: int) -> int:
    """Return the runner's address-space limit (MB) for sandboxes of ``sandbox_mb``.

    A sandbox's limit is set by the runner's child, which without ``CAP_SYS_RESOURCE``
    cannot raise a hard limit above the runner's: a smaller runner limit would fail every
    sandbox's start (issue: ``--memory 8192`` zeroed the class).
    """
    return max(RUNNER_MEMORY_MB, int(sandbox_mb))


def _runner_limits(memory_mb: int) -> Callable[[], None]:
    """Return what the runner runs between fork and exec: bounded memory, and death with the grader."""
    def apply() -> None:
        mem = runner_memory_mb(memory_mb) * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        try:
            ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    return apply


def _spawn(tmp: str, memory_mb: int) -> subprocess.Popen:
    """Start a runner process (its folder ``tmp``, inside the grading's own folder)."""
    env = dict(os.environ, PYTEST_DISABLE_PLUGIN_AUTOLOAD="1", PYTHONDONTWRITEBYTECODE="1")
    env[HOME_ENV] = os.path.dirname(tmp)
    env.pop("PYTEST_ADDOPTS", None)
    return subprocess.Popen([sys.executable, "-E", "-s", "-P", "-c", RUNNER_BOOT.format(root=PACKAGE_ROOT)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            start_new_session=True, env=env, cwd=os.path.abspath(os.sep),
                            preexec_fn=_runner_limits(memory_mb))


def run_runner(job: dict, walls: list[float], on_item: Callable[[str, dict], None]) -> tuple[set, str, str]:
    """Start one runner, feed it the job, hand each finished item to ``on_item(key, outcome)``.

    ``walls[k]`` is the wall-clock budget of item ``k``, counted from the moment the item
    before it finished (the runner grades items in order): an item that overruns costs
    its own budget only. Returns the keys finished, why not all, and the key of the item
    that overran its budget (``""`` if none). The runner's temporary folder is the
    grader's: removed here however the runner ended.
    """
    job = dict(job)
    tmp = tempfile.mkdtemp(prefix="runner-", dir=job.pop("home", None))
    job["tmp"] = tmp
    order = [it["key"] for it in job["items"]]
    keys = set(order)
    overran, why = "", ""
    done: set = set()
    proc = _spawn(tmp, int(job.get("memory_mb", 0)))
    sel = selectors.DefaultSelector()
    fd = proc.stdout.fileno()
    sel.register(fd, selectors.EVENT_READ)
    prefix = job["nonce"].encode() + b" "
    try:
        buf, total, ready = b"", 0, False
        deadline = time.monotonic() + RUNNER_SLACK
        while True:
            if STOP.is_set():
                why = "grading was interrupted"
                break
            left = deadline - time.monotonic()
            if left <= 0:
                if ready:
                    overran = next((k for k in order if k not in done), "")
                    why = (f"timed out (wall-clock limit of {walls[len(done)]:.0f} s for one exercise "
                           "of one submission)")
                else:
                    why = NOT_STARTED
                break
            if not sel.select(timeout=min(left, 0.5)):
                continue
            chunk = os.read(fd, 1 << 16)
            if not chunk:
                break
            total += len(chunk)
            if total > MAX_RUNNER_OUTPUT:
                why = "the test runner wrote too much"
                break
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                if not ready:
                    if line != b"ready":
                        return done, NOT_STARTED, ""
                    ready = True  # non-dumpable now: the nonce may go out
                    deadline = time.monotonic() + walls[0]
                    proc.stdin.write(json.dumps(job).encode())
                    proc.stdin.close()
                    continue
                if not line.startswith(prefix):
                    continue
                try:
                    msg = json.loads(line[len(prefix):])
                except ValueError:
                    continue
                key = str(msg.get("key")) if isinstance(msg, dict) else ""
                if key in keys and key not in done and isinstance(msg.get("outcome"), dict):
                    done.add(key)
                    if len(done) < len(walls):
                        deadline = time.monotonic() + walls[len(done)]
                    on_item(key, msg["outcome"])
    except (BrokenPipeError, OSError):
        why = why or "the test runner stopped"
    finally:
        sel.close()
        _killpg(proc)
        shutil.rmtree(tmp, ignore_errors=True)
    if len(done) < len(keys) and not why:
        why = f"the test runner stopped (exit code {proc.returncode})"
    return done, why, overran


def _killpg(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    for stream in (proc.stdin, proc.stdout):
        try:
            stream.close()
        except (OSError, ValueError):
            pass
    proc.wait()
