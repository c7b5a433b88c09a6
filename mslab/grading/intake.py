"""What a class hands in: which entries are submissions, and each student's files, read once.

The rule (documented in the README) that tells one submission from a class of them:

``--layout submission``
    the folder is one student's work;
``--layout class``
    every entry of the folder is one student's: a folder, a ``.zip``, or a single
    ``.py`` / ``.ipynb`` file (graded as the one exercise given with ``--exercise``);
``--layout auto`` (the default)
    the folder is one submission when it holds an exercise's file where a submission
    keeps it (``NN_topic/<module>.py`` or ``.ipynb``, or ``<module>.py`` itself, the flat
    upload of the platforms), otherwise a class. A student folder *named* like an
    exercise (``01_spring_force/``) is a student like any other: only the file inside
    decides. One entry never decides for the others: a folder holding an exercise's file
    and entries that look like students' (:func:`mslab.grading.layout._student_like`) is
    refused with a request for ``--layout``.

Every entry of a class gets a row: what cannot be graded (a hidden ``.name``, a file of
another kind, a symbolic link) is a submission with the reason it was refused.

A student's file is read exactly once (the snapshot the grading uses): every component
of its path opened relative to the previous one without following symbolic links, the
file itself only if it is a regular file with a single link. A ``.zip`` is unpacked by a
sandbox (:mod:`mslab.grading.unpack`), never in the grader; a notebook is graded from its
code cells.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

from mslab.grading.report import printable
from mslab.grading.unzip import MAX_DEPTH, MAX_MEMBERS, MAX_SOURCE, MAX_ZIP, is_source, name_problem

LAYOUTS = ("auto", "class", "submission")
#: how a gradebook's journal ends (``gradebook.csv.journal``): skipped in a class folder
JOURNAL_SUFFIX = ".journal"
O_READ = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)


@dataclass
class Submission:
    """One row of the gradebook: a student's folder, zip or single file, or why it is refused."""

    path: Path
    name: str
    kind: str = "folder"  # folder | zip | file
    refusal: str = ""
    #: a zip's files once unpacked (:func:`mslab.grading.unpack.unpack_zip`)
    files: dict[str, bytes] | None = field(default=None, repr=False)


def _read_fd(fd: int, label: str) -> tuple[bytes | None, str]:
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        if not stat.S_ISREG(st.st_mode):
            return None, f"{label} is not a regular file (refused)"
        if st.st_nlink != 1:
            return None, f"{label} has {st.st_nlink} hard links (refused: submit a plain copy)"
        if st.st_size > MAX_SOURCE:
            return None, f"{label} is larger than {MAX_SOURCE} bytes"
        return fh.read(MAX_SOURCE + 1)[:MAX_SOURCE], ""


def read_path(base: Path, parts: list[str]) -> tuple[bytes | None, str]:
    """Read ``base/parts...`` once, no component a symbolic link; ``(None, why)`` if it cannot be."""
    label = parts[-1]
    try:
        dir_fd = os.open(base, O_READ | os.O_DIRECTORY)
    except OSError as err:
        return None, f"{base.name or base} could not be opened ({err.strerror})"
    try:
        for part in parts[:-1]:
            try:
                nxt = os.open(part, O_READ | os.O_DIRECTORY, dir_fd=dir_fd)
            except FileNotFoundError:
                return None, "missing"
            except OSError as err:
                return None, (f"{part} is a symbolic link (refused)" if os.path.islink(base / part)
                              else f"{part} could not be opened ({err.strerror})")
            os.close(dir_fd)
            dir_fd = nxt
        try:
            fd = os.open(parts[-1], O_READ, dir_fd=dir_fd)
        except FileNotFoundError:
            return None, "missing"
        except OSError as err:
            if err.errno == 40:  # ELOOP: the file is a symbolic link
                return None, f"{label} is a symbolic link (refused)"
            return None, f"{label} could not be read ({err.strerror})"
        return _read_fd(fd, label)
    finally:
        os.close(dir_fd)


def notebook_code(data: bytes, label: str) -> tuple[str | None, str]:
    """Return the code cells of a notebook, joined (magics and shell lines commented out)."""
    try:
        doc = json.loads(data.decode("utf-8", errors="replace"))
        cells = [c for c in doc["cells"] if isinstance(c, dict) and c.get("cell_type") == "code"]
        texts = ["".join(c["source"]) if isinstance(c["source"], list) else str(c["source"]) for c in cells]
    except (ValueError, KeyError, TypeError):
        return None, f"{label} is not a readable notebook (refused)"
    lines = []
    for text in texts:
        lines += [("# " + ln) if ln.lstrip().startswith(("%", "!")) else ln for ln in text.splitlines()]
        lines.append("")
    return "\n".join(lines), ""


def read_zip(path: Path) -> tuple[bytes | None, str]:
    """Read a submitted zip's bytes once (no link followed, a regular file, at most ``MAX_ZIP``)."""
    try:
        fd = os.open(path, O_READ)
    except OSError as err:
        return None, f"{path.name} could not be read ({err.strerror})"
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
            return None, f"{path.name} is not a regular file (refused)"
        data = fh.read(MAX_ZIP + 1)
    if len(data) > MAX_ZIP:
        return None, f"{path.name} is larger than {MAX_ZIP} bytes (refused)"
    return data, ""


def read_tree(folder: Path) -> tuple[dict[str, bytes] | None, str]:
    """Read the files a zip was unpacked into, as plain data: ``{"a/b.py": bytes}`` or None and why.

    Every folder and file is opened relative to its parent without following a link; only
    regular files with one link, named by the unpacker's rules (:func:`unzip.name_problem`,
    ``.py`` / ``.ipynb``), at most ``MAX_MEMBERS`` of at most ``MAX_SOURCE`` bytes, ``MAX_DEPTH`` deep
    (a refusal names the first rule broken: the unpacker that wrote them is not trusted either).
    """
    files: dict[str, bytes] = {}
    todo = [(os.open(folder, O_READ | os.O_DIRECTORY), "")]
    seen = 0
    try:
        while todo:
            dir_fd, prefix = todo.pop()
            try:
                names = sorted(os.listdir(dir_fd))
                for name in names:
                    rel, seen = prefix + name, seen + 1
                    too_many = seen > MAX_MEMBERS * MAX_DEPTH or len(files) >= MAX_MEMBERS
                    if too_many or rel.count("/") > MAX_DEPTH:
                        return None, f"unpacked into over {MAX_MEMBERS} files or {MAX_DEPTH} levels (refused)"
                    st = os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
                    if stat.S_ISDIR(st.st_mode):
                        todo.append((os.open(name, O_READ | os.O_DIRECTORY, dir_fd=dir_fd), rel + "/"))
                        continue
                    if not stat.S_ISREG(st.st_mode):
                        return None, f"unpacked {printable(rel, 80)!r}, not a regular file (refused)"
                    if name_problem(rel) or not is_source(rel):
                        return None, f"unpacked an unexpected file {printable(rel, 80)!r} (refused)"
                    data, why = _read_fd(os.open(name, O_READ, dir_fd=dir_fd), printable(rel, 80))
                    if data is None:
                        return None, why
                    files[rel] = data
            finally:
                os.close(dir_fd)
    except OSError as err:
        return None, f"the unpacked files could not be read ({err.strerror})"
    finally:
        for dir_fd, _ in todo:
            os.close(dir_fd)
    return files, ""


def is_grader_file(path: Path) -> bool:
    """Tell whether ``path`` is a gradebook's journal (``*.journal``): a grader's file, never a student."""
    return path.name.endswith(JOURNAL_SUFFIX) and path.is_file() and not path.is_symlink()


def class_entry(path: Path, single: bool) -> Submission:
    """One entry of a class folder as a submission, or refused with its reason."""
    name = path.name
    stem = name.rsplit(".", 1)[0] if not path.is_dir() or path.is_symlink() else name
    if name.startswith("."):
        return Submission(path, name, refusal=f"{name}: a hidden entry (name starts with '.'): not graded")
    if path.is_symlink():
        return Submission(path, name, refusal="the submission is a symbolic link (refused)")
    if path.is_dir():
        return Submission(path, name)
    if name.endswith(".zip"):
        return Submission(path, stem, kind="zip")
    if name.endswith((".py", ".ipynb")):
        refusal = "" if single else f"{name}: a single file needs one --exercise (the one it answers)"
        return Submission(path, stem, kind="file", refusal=refusal)
    return Submission(path, name, refusal=f"{name}: not a folder, .zip, .py or .ipynb: not graded")


def unique_names(subs: list[Submission]) -> list[Submission]:
    """Give every submission a row name of its own (shown as :func:`printable`, at most 120 characters).

    A name that two entries share (``bob/`` and ``bob.zip``) becomes the entry's full name
    (``bob.zip``); one still shared (names cut at 120 characters) keeps its first 111
    characters and gets ``~`` and 8 hex digits of the entry's path. The same path twice
    is the same student, with the same name.
    """
    shown = [printable(s.name) for s in subs]
    for step in (lambda s: printable(s.path.name or str(s.path)), _hashed):
        paths: dict[str, set[str]] = {}
        for s, name in zip(subs, shown, strict=True):
            paths.setdefault(name, set()).add(os.path.abspath(s.path))
        shared = {name for name, where in paths.items() if len(where) > 1}
        shown = [step(s) if name in shared else name for s, name in zip(subs, shown, strict=True)]
    for s, name in zip(subs, shown, strict=True):
        s.name = name
    return subs


def _hashed(sub: Submission) -> str:
    digest = hashlib.sha256(os.fsencode(os.path.abspath(sub.path))).hexdigest()[:8]
    return f"{printable(sub.path.name or str(sub.path), 111)}~{digest}"
