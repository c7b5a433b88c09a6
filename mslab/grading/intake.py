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
    decides, and a folder that looks both ways is refused with a request for
    ``--layout``.

Every entry of a class gets a row: what cannot be graded (a hidden ``.name``, a file of
another kind, a symbolic link) is a submission with the reason it was refused.

A student's file is read exactly once (the snapshot the grading uses): every component
of its path opened relative to the previous one without following symbolic links, the
file itself only if it is a regular file with a single link. A ``.zip`` is read in
memory under limits (members, sizes, no absolute or ``..`` names); a notebook is graded
from its code cells.
"""

from __future__ import annotations

import io
import json
import os
import posixpath
import stat
import zipfile
from dataclasses import dataclass
from pathlib import Path

#: largest student file the grader reads (bytes)
MAX_SOURCE = 1_000_000
#: limits of a submitted .zip: its own size, its members, their total unpacked size
MAX_ZIP, MAX_MEMBERS, MAX_UNPACKED = 20_000_000, 1000, 50_000_000
LAYOUTS = ("auto", "class", "submission")
O_READ = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)


@dataclass
class Submission:
    """One row of the gradebook: a student's folder, zip or single file, or why it is refused."""

    path: Path
    name: str
    kind: str = "folder"  # folder | zip | file
    refusal: str = ""


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


def zip_files(path: Path) -> tuple[dict[str, bytes] | None, str]:
    """Return the ``.py`` / ``.ipynb`` members of a submitted zip, in memory (a common top folder dropped)."""
    data, why = _read_zip(path)
    if data is None:
        return None, why
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
        infos = zf.infolist()
        if len(infos) > MAX_MEMBERS:
            return None, f"{path.name} has more than {MAX_MEMBERS} members (refused)"
        if sum(i.file_size for i in infos) > MAX_UNPACKED:
            return None, f"{path.name} unpacks to more than {MAX_UNPACKED} bytes (refused)"
        out: dict[str, bytes] = {}
        for info in infos:
            name = info.filename
            if (info.is_dir() or name.startswith("/") or "\\" in name or ".." in name.split("/")
                    or not name.endswith((".py", ".ipynb")) or info.file_size > MAX_SOURCE):
                continue
            with zf.open(info) as fh:
                out[posixpath.normpath(name)] = fh.read(MAX_SOURCE + 1)[:MAX_SOURCE]
    except (zipfile.BadZipFile, OSError, ValueError, NotImplementedError, EOFError):
        return None, f"{path.name} is not a readable zip (refused)"
    tops = {n.split("/")[0] for n in out}
    if len(tops) == 1 and all("/" in n for n in out):
        out = {n.split("/", 1)[1]: v for n, v in out.items()}
    return out, ""


def _read_zip(path: Path) -> tuple[bytes | None, str]:
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
