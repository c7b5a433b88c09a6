"""The student release: solutions replaced by ``raise NotImplementedError``, hidden tests left out."""

from __future__ import annotations

import ast
import os
import shutil
import tempfile
from pathlib import Path

from mslab.grading.layout import BEGIN, END, EXERCISE_NAME, HIDDEN

#: never copied into a release
SKIP_DIRS = {"__pycache__", ".pytest_cache", ".ipynb_checkpoints", ".ruff_cache"}
SKIP_SUFFIXES = {".pyc", ".pyo"}


def strip_solutions(text: str, filename: str = "<source>") -> str:
    """Replace every ``# BEGIN SOLUTION`` ... ``# END SOLUTION`` block by one ``raise``.

    The ``raise NotImplementedError`` keeps the indentation of the BEGIN line. Unbalanced
    markers raise ValueError naming the line; so does a result that does not parse.
    """
    out: list[str] = []
    inside = None
    for number, line in enumerate(text.splitlines(keepends=True), start=1):
        marker = line.strip()
        if marker.startswith(BEGIN):
            if inside is not None:
                raise ValueError(f"{filename}:{number}: '{BEGIN}' inside a solution block "
                                 f"(opened line {inside})")
            inside = number
            indent = line[: len(line) - len(line.lstrip())]
            out.append(f"{indent}raise NotImplementedError\n")
        elif marker.startswith(END):
            if inside is None:
                raise ValueError(f"{filename}:{number}: '{END}' without '{BEGIN}'")
            inside = None
        elif inside is None:
            out.append(line)
    if inside is not None:
        raise ValueError(f"{filename}:{inside}: '{BEGIN}' is never closed")
    result = "".join(out)
    try:
        ast.parse(result, filename=filename)
    except SyntaxError as err:
        raise ValueError(f"{filename}: the student version does not parse: {err}") from None
    return result


def solution_lines(text: str) -> list[str]:
    """The stripped, non-empty lines inside solution blocks (what a release must not contain)."""
    lines, inside = [], False
    for line in text.splitlines():
        marker = line.strip()
        if marker.startswith(BEGIN):
            inside = True
        elif marker.startswith(END):
            inside = False
        elif inside and marker:
            lines.append(marker)
    return lines


def _released_files(src: Path):
    """(relative path, source path) of everything that goes into the release."""
    for dirpath, dirnames, filenames in os.walk(src):
        dirnames[:] = sorted(d for d in dirnames if d not in SKIP_DIRS and not d.startswith("."))
        rel_dir = Path(dirpath).relative_to(src)
        for name in sorted(filenames):
            path = Path(dirpath) / name
            skip = name.startswith(".") or path.suffix in SKIP_SUFFIXES or HIDDEN.match(name)
            if skip or path.is_symlink():
                continue
            yield rel_dir / name, path


def release(src: str | Path, dest: str | Path, force: bool = False) -> list[Path]:
    """Write the student version of ``src`` into ``dest``; returns the files written.

    The release is built in a temporary sibling folder and renamed into place, so a
    failure (say, unbalanced markers) leaves no half release behind.
    """
    src, dest = Path(src).resolve(), Path(dest).resolve()
    if not src.is_dir():
        raise ValueError(f"{src}: no such folder")
    if dest == src or dest.is_relative_to(src) or src.is_relative_to(dest):
        raise ValueError(f"{dest}: the release must be outside the source folder {src}")
    if not any(EXERCISE_NAME.match(p.name) for p in src.iterdir() if p.is_dir()):
        raise ValueError(f"{src}: no exercise folders (NN_topic) found")
    if dest.exists() and any(dest.iterdir()) and not force:
        raise ValueError(f"{dest}: exists and is not empty (use --force to replace it)")
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}-", dir=dest.parent))
    written = []
    try:
        for rel, path in _released_files(src):
            target = tmp / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            if path.suffix == ".py":
                text = path.read_text()
                target.write_text(strip_solutions(text, str(rel)) if BEGIN in text else text)
            else:
                shutil.copyfile(path, target)
            written.append(dest / rel)
        if dest.exists():
            shutil.rmtree(dest)
        os.replace(tmp, dest)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return written
