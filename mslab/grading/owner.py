"""Ownership of what a grader leaves on the machine, valid across PID namespaces.

A grading owns one temporary folder, ``<tmp>/mslab-grade-<token>/``, and holds an
exclusive ``flock`` on the file ``.owner`` inside it from creation to removal. Its runner
folders live inside it, and its parent cgroup bears the same name. Whoever starts later
(another grader, in another container, CI job or PID namespace over the same temporary
folder) removes a folder or cgroup only if it can take that lock itself: the kernel drops
the lock when the last descriptor of its holder closes, so a killed grader's folder is
free and a live one's never is, whatever PIDs either process sees.

The folder is built under a hidden name (``.mslab-grade-build-...``), locked, then renamed:
a folder with the live name always has a lock to test. A grader killed inside those few
system calls leaves its ``.mslab-grade-build-*`` folder behind (never removed by others).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import secrets
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

#: name of every grading's folder and parent cgroup: PREFIX + a random token
PREFIX = "mslab-grade-"
OWNER = ".owner"


class Owned:
    """The grading's folder, locked for as long as this object is open."""

    def __init__(self, base: str | Path | None = None):
        base = Path(base or tempfile.gettempdir())
        self.name = f"{PREFIX}{secrets.token_hex(8)}"
        build = Path(tempfile.mkdtemp(prefix=f".{PREFIX}build-", dir=base))
        self._fd = os.open(build / OWNER, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o600)
        fcntl.flock(self._fd, fcntl.LOCK_EX)
        self.folder = base / self.name
        os.chmod(build, 0o711)  # a throwaway uid may pass to its stage (rlimits as root), not list
        os.rename(build, self.folder)

    def close(self) -> None:
        """Remove the folder (still locked), then release the lock."""
        if self._fd < 0:
            return
        shutil.rmtree(self.folder, ignore_errors=True)
        os.close(self._fd)
        self._fd = -1


def is_abandoned(folder: Path) -> bool:
    """Tell whether a grading folder's owner is gone (its lock is free); False when unsure."""
    try:
        fd = os.open(folder / OWNER, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return False  # no lock to test (not ours, or being removed): leave it
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    finally:
        os.close(fd)
    return True


def clean_abandoned(base: str | Path | None = None) -> None:
    """Remove the grading folders of graders that have ended without removing them."""
    for folder in Path(base or tempfile.gettempdir()).glob(f"{PREFIX}*"):
        if folder.is_dir() and not folder.is_symlink() and is_abandoned(folder):
            shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def closed_to_others(paths: list[str | Path]) -> Iterator[None]:
    """Close folders to other users (mode 0700) while grading, then give them their mode back.

    Used when student code runs as a throwaway uid without namespaces (rlimits as root):
    the instructor's tree and the submissions become unreadable to it.
    """
    changed = []
    try:
        for path in dict.fromkeys(os.path.realpath(p) for p in paths):
            mode = os.stat(path).st_mode & 0o7777
            if mode & 0o077:
                os.chmod(path, mode & 0o7700)
                changed.append((path, mode))
        yield
    finally:
        for path, mode in changed:
            os.chmod(path, mode)
