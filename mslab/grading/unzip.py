"""The unpacker: the only process that decompresses a student's ``.zip``.

Started by the grader like a sandbox (same isolation, its own resource box, the limits of
one test: :mod:`mslab.grading.unpack`) as ``python -I -S unzip.py ZIP OUT``. Standard
library only (it runs where mslab is not importable). It checks the whole central
directory first, then writes the ``.py`` / ``.ipynb`` members into the empty folder
``OUT`` (a member's folders made as needed, every file created exclusively) and prints one
JSON line: ``{"ok": true}`` or ``{"ok": false, "why": KIND, "member": NAME}`` with KIND a
key of :data:`REFUSALS`. A zip with any member it refuses is refused as a whole.

Everything here reads the student's data only: nothing in the zip is run. The grader
trusts none of it: it reads ``OUT`` back as plain data by the same rules
(:func:`name_problem`, the size caps) and decides the kind of any failure it saw itself.
"""

from __future__ import annotations

import json
import os
import stat
import sys
import zipfile

#: largest student file the grader reads (bytes)
MAX_SOURCE = 1_000_000
#: limits of a submitted .zip: its own size, its members, their total unpacked size
MAX_ZIP, MAX_MEMBERS, MAX_UNPACKED = 20_000_000, 1000, 50_000_000
#: folder levels of a member's name at most
MAX_DEPTH = 16
#: the members unpacked (everything else is skipped, unread); folders macOS adds are skipped too
SOURCES, SKIPPED = (".py", ".ipynb"), "__MACOSX/"
#: why a zip is refused (``{member}`` is the member's name)
REFUSALS = {
    "corrupt": "is not a readable zip (refused)",
    "members": f"has more than {MAX_MEMBERS} members (refused)",
    "unpacked": f"unpacks to more than {MAX_UNPACKED} bytes (refused)",
    "name": "member {member}: an absolute, '..' or backslash name (refused)",
    "symlink": "member {member} is a symbolic link (refused)",
    "encrypted": "member {member} is encrypted (refused)",
    "nested": "member {member} is a zip inside the zip (refused: zip the files themselves)",
    "large": f"member {{member}} is larger than {MAX_SOURCE} bytes (refused)",
    "twice": "member {member} appears twice (refused)",
    "deep": f"member {{member}} is more than {MAX_DEPTH} folders deep (refused)",
    "memory": "ran out of memory while unpacking",
}
CHUNK = 1 << 16


class Refused(Exception):
    """The zip is refused: ``kind`` (a key of :data:`REFUSALS`) and the member concerned."""

    def __init__(self, kind: str, member: str = ""):
        super().__init__(kind)
        self.kind, self.member = kind, member


def name_problem(name: str) -> bool:
    """Tell whether a member's (or unpacked file's) name is unsafe: absolute, ``..``, backslash, NUL."""
    parts = name.split("/")
    return (name.startswith("/") or "\\" in name or "\0" in name or ".." in parts
            or ":" in parts[0] or not name.strip("/"))


def is_source(name: str) -> bool:
    """Tell whether a member is unpacked: a ``.py`` / ``.ipynb`` file outside ``__MACOSX/``."""
    return name.endswith(SOURCES) and not name.startswith(SKIPPED)


def check(infos: list[zipfile.ZipInfo]) -> list[zipfile.ZipInfo]:
    """Refuse the zip for what its central directory says; return the members to unpack."""
    if len(infos) > MAX_MEMBERS:
        raise Refused("members")
    if sum(i.file_size for i in infos) > MAX_UNPACKED:
        raise Refused("unpacked")
    seen: set[str] = set()
    for info in infos:
        name = info.filename
        if name_problem(name):
            raise Refused("name", name)
        if name.rstrip("/").count("/") > MAX_DEPTH:
            raise Refused("deep", name)
        if stat.S_ISLNK(info.external_attr >> 16):
            raise Refused("symlink", name)
        if info.flag_bits & 0x1:
            raise Refused("encrypted", name)
        if name.lower().endswith(".zip"):
            raise Refused("nested", name)
        key = name.rstrip("/")
        if key in seen:
            raise Refused("twice", name)
        seen.add(key)
        if is_source(name) and info.file_size > MAX_SOURCE:
            raise Refused("large", name)
    return [i for i in infos if not i.is_dir() and is_source(i.filename)]


def unpack(zf: zipfile.ZipFile, info: zipfile.ZipInfo, out: str) -> None:
    """Write one member below ``out`` (its folders made, the file created exclusively, size capped)."""
    parts = [p for p in info.filename.split("/") if p not in ("", ".")]
    folder = out
    for part in parts[:-1]:
        folder = os.path.join(folder, part)
        try:
            os.mkdir(folder, 0o700)
        except FileExistsError:
            if os.path.islink(folder) or not os.path.isdir(folder):  # a file of that name came first
                raise Refused("twice", info.filename) from None
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW
    try:
        fd = os.open(os.path.join(folder, parts[-1]), flags, 0o600)
    except (FileExistsError, IsADirectoryError):
        raise Refused("twice", info.filename) from None
    written = 0
    with os.fdopen(fd, "wb") as dst, zf.open(info) as src:
        while chunk := src.read(CHUNK):
            written += len(chunk)
            if written > MAX_SOURCE:
                raise Refused("large", info.filename)
            dst.write(chunk)


def main() -> None:
    """Unpack ``sys.argv[1]`` into ``sys.argv[2]``; print the verdict as one JSON line."""
    path, out = sys.argv[1], sys.argv[2]
    try:
        with zipfile.ZipFile(path) as zf:
            for info in check(zf.infolist()):
                unpack(zf, info, out)
        verdict = {"ok": True}
    except Refused as err:
        verdict = {"ok": False, "why": err.kind, "member": err.member[:200]}
    except MemoryError:
        verdict = {"ok": False, "why": "memory", "member": ""}
    except Exception:  # noqa: BLE001 - BadZipFile, zlib/bz2/lzma errors, a bad method: unreadable
        verdict = {"ok": False, "why": "corrupt", "member": ""}
    sys.stdout.write(json.dumps(verdict) + "\n")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
