"""The runner as its sandboxes' child subreaper: what a sandbox leaves behind dies with it.

In the namespace modes a sandbox's processes die with its PID namespace, and ``rlimits``
as root kills every process of its throwaway uid. ``rlimits`` as a user without a cgroup
has neither: a daemon that calls ``setsid`` (and forks again) leaves the sandbox's
session and, orphaned, would be adopted by init and outlive grading. The runner
therefore marks itself a *child subreaper* (``prctl(PR_SET_CHILD_SUBREAPER)``): orphans of
its sandboxes are adopted by the runner instead, and once a sandbox is closed every child
the runner still has is one of them (the runner starts no other process) and is killed.
"""

from __future__ import annotations

import ctypes
import os
import signal

PR_SET_CHILD_SUBREAPER = 36
#: rounds of killing: each kills the runner's children, whose own orphans it then adopts
MAX_ROUNDS = 200
_ACTIVE = False


def become_subreaper() -> bool:
    """Make this process the subreaper of its descendants (Linux); True if it is now."""
    global _ACTIVE
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        _ACTIVE = libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        _ACTIVE = False
    return _ACTIVE


def _children(pid: int) -> list[int]:
    """Return the processes whose parent is ``pid`` (from /proc)."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat", "rb") as fh:
                    stat = fh.read()
            except OSError:
                continue
            fields = stat[stat.rfind(b")") + 2:].split()
            if len(fields) > 1 and int(fields[1]) == pid:
                found.append(int(entry))
    return found


def kill_orphans() -> None:
    """Kill and reap every child of this subreaper (no-op unless :func:`become_subreaper` ran)."""
    if not _ACTIVE:
        return
    me = os.getpid()
    for _ in range(MAX_ROUNDS):
        children = _children(me)
        if not children:
            return
        for pid in children:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        for pid in children:
            try:
                os.waitpid(pid, 0)
            except ChildProcessError:
                pass
