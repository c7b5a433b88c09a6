"""Issue 11, "what a newcomer trips over": one test per defect, each reproducing it first.

Runs that announce their cost and refuse what cannot fit in memory, cheap checks before
expensive ones, feedback by the clock, timings without compilation, files others can read.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np

from mslab.commands.common import atomic_write

ROOT = Path(__file__).resolve().parents[1]


# -- defect 4: files written with the umask's permissions --------------------------------------------
def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_atomic_write_gives_the_umask_mode_not_0600(tmp_path):
    old = os.umask(0o022)
    try:
        plain = tmp_path / "plain.txt"
        plain.write_text("x")  # what an ordinary open() gives: the reference
        written = atomic_write(tmp_path / "data.npz", lambda tmp: np.savez(tmp, a=np.zeros(3)))
        assert _mode(written) == _mode(plain) == 0o644
        os.umask(0o077)
        private = atomic_write(tmp_path / "private.txt", lambda tmp: Path(tmp).write_text("y"))
        assert _mode(private) == 0o600
    finally:
        os.umask(old)


def test_atomic_write_keeps_an_existing_files_mode(tmp_path):
    path = tmp_path / "table.csv"
    path.write_text("old")
    path.chmod(0o640)
    atomic_write(path, lambda tmp: Path(tmp).write_text("new"))
    assert path.read_text() == "new" and _mode(path) == 0o640
