"""Writing files the way every part of mslab does: atomically, with an ordinary file's mode.

Outputs (figures, run data, JSON, gradebooks) are written to a temporary file in the same
folder and renamed into place, so a reader never sees half a file and an interrupted
write leaves nothing behind. The finished file gets the mode ``open(path, "w")`` would give
it (``0o666`` less the umask; an existing file keeps its mode), not the ``0o600`` of a
temporary file, so a course server can serve it.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path


def current_umask() -> int:
    """Return the process's umask (read without changing it where ``/proc`` tells it)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # no /proc: set and restore (not thread-safe, but brief)
    os.umask(mask)
    return mask


def file_mode(path: Path) -> int:
    """Return the mode for a new file at ``path``: an existing file's mode, else ``0o666 & ~umask``."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~current_umask()


def atomic_write(path: str | Path, write: Callable[[str], None], suffix: str | None = None) -> Path:
    """Call ``write(tmp_path)``, then rename tmp to ``path``: readers never see a half file.

    The temporary file sits in the same folder (same file system, so the rename is atomic)
    and is removed if ``write`` fails or is interrupted. The finished file has the mode of
    :func:`file_mode`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mode = file_mode(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=suffix or path.suffix, dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, mode)  # mkstemp made it 0600; the finished file gets the umask's mode
        os.replace(tmp, path)
    except BaseException as err:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(err, OSError) and err.errno == errno.ENOSPC:  # name the file, not only [Errno 28]
            raise OSError(err.errno, f"{path}: no space left on the device while writing it") from None
        raise
    return path


def _mb(n_bytes: float) -> str:
    return f"{n_bytes / 2**20:.3g} MB"


def output_problem(folder: str | Path, need_bytes: int = 0) -> str | None:
    """Say why outputs cannot be written into ``folder`` (None: they can), before any is computed.

    ``folder`` may not exist yet (it is not created here): it must not be a file, its nearest
    existing parent must be a folder this process can create files in (tested by creating and
    removing an empty file: read-only mounts and permissions alike), and that file system must
    have ``need_bytes`` free.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        return f"{folder} exists and is not a folder"
    base = folder.absolute()
    while not base.exists() and base != base.parent:
        base = base.parent
    if not base.is_dir():
        return f"{base} is a file, so the folder {folder} cannot be made"
    try:
        fd, probe = tempfile.mkstemp(prefix=".mslab-probe-", dir=base)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        return f"cannot write in {base} ({err.strerror or err})"
    free = shutil.disk_usage(base).free
    if free < need_bytes:
        return f"only {_mb(free)} free on the file system of {base}; the outputs need about {_mb(need_bytes)}"
    return None


#: longest scene name that becomes a file-name stem (with ``_energy.png`` far below 255 bytes)
MAX_STEM = 100


def name_problem(name: object) -> str | None:
    r"""Say why a scene ``name`` cannot become an output file name (None: it can).

    The one rule of what a scene name may be, read by the scene loader (so ``mslab validate``
    refuses what ``mslab run`` would refuse) and by :func:`file_stem`: a non-empty string of at
    most :data:`MAX_STEM` characters that is not a path (no ``/`` or ``\``, not ``.`` or
    ``..``, no leading dot) and holds no control character (NUL, newline, ...) and no invisible
    format or line-separator character (U+202E, which reverses how the text after it shows).
    """
    if not isinstance(name, str):
        return f"must be a string, got {type(name).__name__}"
    if not name:
        return "must not be empty (output files are named after it)"
    if len(name) > MAX_STEM:
        return f"is {len(name)} characters long, more than {MAX_STEM} (output files are named after it)"
    if "/" in name or "\\" in name:
        return "is a name, not a path: no '/' or '\\' (output files are named after it)"
    if name.startswith("."):
        return "must not start with '.' (output files are named after it: '..' or a hidden file)"
    import unicodedata

    bad = next((c for c in name if unicodedata.category(c) in ("Cc", "Cf", "Cs", "Zl", "Zp")), None)
    if bad is not None:  # (Cf: format characters such as U+202E, which reverses the text shown after it)
        kind = "control" if unicodedata.category(bad) == "Cc" else "invisible format or separator"
        return f"holds the {kind} character {bad!r} (U+{ord(bad):04X}; output files are named after it)"
    return None


def file_stem(name: object) -> str:
    """Return the file-name stem of the outputs of scene ``name``: a name, never a path.

    A name :func:`name_problem` refuses raises ``ValueError`` naming the reason; in an accepted
    name every character other than letters, digits, ``-``, ``_`` and ``.`` becomes ``_``
    (spaces, accents, ``$``, ``~``, ``:``), so every file written from the stem stays in the
    folder it is joined to.
    """
    import re

    problem = name_problem(name)
    if problem:
        from mslab.checks import shown

        raise ValueError(f"scene name {shown(name)}: {problem}")
    return re.sub(r"[^A-Za-z0-9._-]", "_", str(name))
