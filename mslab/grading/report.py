"""What the grader writes: score sheets, the CSV gradebook and the journal of a class.

Every name that comes from a student's folder is shown sanitised: control characters
escaped in reports (a newline cannot forge a summary line) and CSV cells that a
spreadsheet would run as a formula (``= + - @``, tab, CR) prefixed with ``'``.
"""

from __future__ import annotations

import csv
import fcntl
import hashlib
import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mslab.files import atomic_write

if TYPE_CHECKING:
    from mslab.grading.autograde import SubmissionResult
    from mslab.grading.layout import Exercise


def printable(text: str, limit: int = 120) -> str:
    r"""Return ``text`` with control and non-printable characters as ``\xNN`` escapes, shortened."""
    out = "".join(c if c.isprintable() else f"\\x{ord(c):02x}" if ord(c) < 256 else f"\\u{ord(c):04x}"
                  for c in str(text))
    return out if len(out) <= limit else out[: limit - 3] + "..."


def csv_cell(value: Any) -> str:
    """Return one CSV cell that no spreadsheet evaluates."""
    text = printable(str(value), limit=200)
    return "'" + text if text[:1] in ("=", "+", "-", "@", "\t", "\r") else text


def format_report(result: SubmissionResult) -> str:
    """Return the human-readable score sheet of one submission (a :class:`SubmissionResult`)."""
    lines = [f"{printable(result.student)}  ({printable(result.submission, 200)})"]
    if result.isolation:
        lines.append(f"  isolation: {result.isolation}")
    if result.resources:
        lines.append(f"  resources: {result.resources}")
    for ex in result.exercises:
        lines.append(f"  {ex.name}: {ex.total:g}/{ex.max_points:g}")
        for t in ex.tests:
            mark = "pass" if t.passed else "FAIL"
            tail = "" if t.passed else f"  {printable(t.reason, 200)}"
            lines.append(f"    {t.points:>4g}/{t.max_points:<4g} {mark}  {t.test}{tail}")
    lines.append(f"  total: {result.total:g}/{result.max_points:g}")
    return "\n".join(lines)


def gradebook_rows(results: Sequence[SubmissionResult]) -> list[list[str]]:
    """Return the CSV rows: header, then one row per student (total, max, one column per exercise)."""
    names = [e.name for e in results[0].exercises] if results else []
    rows: list[list[str]] = [["student", "total", "max", *names]]
    for r in results:
        rows.append([csv_cell(r.student), f"{r.total:g}", f"{r.max_points:g}",
                     *(f"{e.total:g}" for e in r.exercises)])
    return rows


def write_csv(path: str | Path, rows: list[list[str]]) -> Path:
    """Write the gradebook atomically (temporary file, then rename) with the umask's permissions."""
    def write(tmp: str) -> None:
        with open(tmp, "w", newline="") as fh:
            csv.writer(fh).writerows(rows)
            fh.flush()
            os.fsync(fh.fileno())

    return atomic_write(path, write)


class Journal:
    """Outcomes of graded items, one JSON line each, appended as they arrive; one grader at a time.

    An item is one exercise of one submission, keyed by the submission's path, the
    exercise and a hash of the student's file; the fingerprint (the instructor's tests and
    the limits, given by :meth:`bind`) must match for an outcome to be reused by
    ``--resume``. The journal is locked (``flock``) from opening to :meth:`close`: a second
    grader on the same gradebook is refused (ValueError) before it reads or truncates
    anything, so it can neither corrupt the first one's lines nor delete them.
    """

    def __init__(self, path: str | Path, resume: bool):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o600)
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._fd)
            raise ValueError(f"{self.path}: another mslab grade is grading into this gradebook "
                             "(its journal is locked); wait for it to finish") from None
        self.fingerprint = ""
        self._lines: list[str] = []
        self.done: dict[str, dict] = {}
        self.added = 0  # outcomes appended by this grading
        if resume:
            with os.fdopen(os.dup(self._fd), "rb") as fh:
                self._lines = fh.read().decode(errors="replace").splitlines()
        else:
            os.ftruncate(self._fd, 0)

    def bind(self, fingerprint: str) -> None:
        """Set the fingerprint of this grading; outcomes journaled under it become :attr:`done`."""
        self.fingerprint = fingerprint
        for line in self._lines:
            try:
                entry = json.loads(line)
            except ValueError:
                continue  # the line in flight when the grader was killed
            if isinstance(entry, dict) and entry.get("fingerprint") == fingerprint:
                self.done[str(entry.get("key"))] = entry.get("outcome")

    def add(self, key: str, outcome: dict | None) -> None:
        """Append the outcome of the item ``key`` and flush it to disk."""
        line = json.dumps({"fingerprint": self.fingerprint, "key": key, "outcome": outcome}) + "\n"
        os.lseek(self._fd, 0, os.SEEK_END)
        os.write(self._fd, line.encode())
        os.fsync(self._fd)
        self.added += 1

    def close(self, finished: bool) -> None:
        """Release the journal; a finished grading removes it first (still holding the lock)."""
        if self._fd < 0:
            return
        if finished:
            self.path.unlink(missing_ok=True)
        os.close(self._fd)
        self._fd = -1


def item_key(submission: Path, exercise: str, source: str | None) -> str:
    """Return the journal key of one exercise of one submission (its path, name and file hash)."""
    digest = hashlib.sha256((source or "").encode()).hexdigest()[:20]
    return f"{os.path.abspath(submission)}\0{exercise}\0{digest}"


def fingerprint(exercises: Iterable[Exercise], timeout: float, memory_mb: int) -> str:
    """Return a hash of the instructor's tests and the limits (a journal is reused only if it matches)."""
    h = hashlib.sha256(f"{timeout}:{memory_mb}".encode())
    for ex in exercises:
        for name, text in sorted(ex.tests.items()):
            h.update(f"{ex.name}/{name}\0{text}\0".encode())
    return h.hexdigest()[:32]
