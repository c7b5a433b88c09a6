"""Reading scene files: TOML text to tables, syntax errors as one line with the line number."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from mslab.errors import SceneError

#: largest scene file read, checked before reading (100,000 particles' positions and springs
#: listed take about 7 MB; larger arrangements come from generators)
MAX_FILE_BYTES = 8 * 2**20
#: deepest nesting of arrays and tables a scene file may use (a scene needs 3: [[x, y], ...])
MAX_DEPTH = 16


def _nesting_problem(text: str) -> tuple[int, int] | None:
    """``(line, depth)`` where brackets outside strings and comments first nest beyond :data:`MAX_DEPTH`.

    Checked before parsing: the parser recurses once per level, so a file nested thousands
    deep would end in a RecursionError.
    """
    depth, line, quote, comment = 0, 1, "", False
    for ch in text:
        if ch == "\n":
            line, comment = line + 1, False
            quote = "" if len(quote) == 1 else quote
        elif comment:
            continue
        elif quote:
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch == "#":
            comment = True
        elif ch in "[{":
            depth += 1
            if depth > MAX_DEPTH:
                return line, depth
        elif ch in "]}":
            depth = max(depth - 1, 0)
    return None


def parse_scene_text(text: str, source: str | None = None) -> dict:
    """Parse TOML text; a syntax error becomes ``SceneError("line N", ...)``.

    A byte-order mark at the start (UTF-8 files written by some Windows editors) is skipped.
    """
    text = text.removeprefix("\ufeff")
    deep = _nesting_problem(text)
    if deep is not None:
        raise SceneError(f"line {deep[0]}", f"arrays or tables nested more than {MAX_DEPTH} deep "
                         f"(a scene needs at most 3: positions = [[x, y], ...])", source)
    try:
        doc = tomllib.loads(text)
    except RecursionError:
        raise SceneError("toml", f"nested too deep to read (more than {MAX_DEPTH} levels)", source) from None
    except tomllib.TOMLDecodeError as err:
        msg = str(err)
        match = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        reason = re.sub(r"\s*\(at line \d+, column \d+\)", "", msg) or "invalid TOML"
        if match:
            key = f"line {match.group(1)}"
            reason = f"TOML syntax error: {reason} (column {match.group(2)})"
        elif "end of document" in msg:
            reason = re.sub(r"\s*\(at end of document\)", "", msg)
            key = f"line {len(text.rstrip().splitlines())}"
            reason = f"TOML syntax error: {reason} (at the end of the file)"
        else:
            key, reason = "toml", f"TOML syntax error: {reason}"
        raise SceneError(key, reason, source) from None
    deep = _deepest(doc)
    if deep is not None:  # dotted keys and headers ([a.b.c...]) nest without brackets
        raise SceneError(deep, f"keys nested more than {MAX_DEPTH} deep (a scene needs at most 3)", source)
    return doc


def _deepest(doc: dict) -> str | None:
    """Return the first dotted key (cut) nested beyond :data:`MAX_DEPTH` tables and arrays, or None.

    Iterative, so a file of 2,000 dotted header parts cannot end in a RecursionError.
    """
    stack: list[tuple[object, str, int]] = [(doc, "", 0)]
    while stack:
        value, key, depth = stack.pop()
        if depth > MAX_DEPTH:
            return key[:80] + ("..." if len(key) > 80 else "")
        if isinstance(value, dict):
            stack.extend((v, f"{key}.{k}" if key else str(k), depth + 1) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend((v, f"{key}[{i}]", depth + 1) for i, v in enumerate(value))
    return None


def read_scene_file(path: Path, source: str) -> dict:
    """Return the tables of a scene file (``source``: how messages name the file)."""
    try:
        size = path.stat().st_size  # the cheap check first: parsing 47 MB takes minutes
        if size > MAX_FILE_BYTES:
            raise SceneError("file", f"{size / 2**20:.3g} MiB, more than the {MAX_FILE_BYTES // 2**20} MiB a "
                             f"scene file may have (checked before reading it); make large arrangements "
                             f"with a generator: [particles] generator = \"grid\" (docs/scenes.md)", source)
        with path.open(encoding="utf-8") as file:  # text mode, as read_text: newlines translated
            text = file.read(MAX_FILE_BYTES + 1)  # (a file grown since its size was read: cut, refused)
        if len(text) > MAX_FILE_BYTES:
            raise SceneError("file", f"more than the {MAX_FILE_BYTES // 2**20} MiB a scene file may have",
                             source)
    except UnicodeDecodeError as err:
        raise SceneError("file", f"not UTF-8 text ({err.reason})", source) from None
    except OSError as err:
        raise SceneError("file", f"cannot be read ({err.strerror or err})", source) from None
    return parse_scene_text(text, source)
