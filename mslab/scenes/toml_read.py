"""Reading scene files: TOML text to tables, syntax errors as one line with the line number."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from mslab.errors import SceneError


def parse_scene_text(text: str, source: str | None = None) -> dict:
    """Parse TOML text; a syntax error becomes ``SceneError("line N", ...)``."""
    try:
        return tomllib.loads(text)
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


def read_scene_file(path: Path, source: str) -> dict:
    """Return the tables of a scene file (``source``: how messages name the file)."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise SceneError("file", f"not UTF-8 text ({err.reason})", source) from None
    except OSError as err:
        raise SceneError("file", f"cannot be read ({err.strerror or err})", source) from None
    return parse_scene_text(text, source)
