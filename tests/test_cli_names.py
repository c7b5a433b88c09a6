"""Scene names are names, not paths: every file ``mslab run`` writes stays inside ``--out`` (issue 37)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from mslab.cli import main
from mslab.files import MAX_STEM, file_stem

PENDULUM = (Path(__file__).parents[1] / "mslab" / "scenes" / "pendulum.toml").read_text()

#: hostile names, as TOML basic-string bodies (escapes included)
HOSTILE = ["../../x", "/tmp/abs_x", "..", ".", "a/../../b", "a\\\\..\\\\b", "nul\\u0000byte", "x" * 5000,
           "line\\nbreak", "", "~/home", "$HOME", "é/ü"]


def files_under(root: Path) -> set[Path]:
    return {Path(d, f) for d, _, names in os.walk(root) for f in names}


@pytest.mark.parametrize("name", HOSTILE, ids=range(len(HOSTILE)))
def test_run_writes_only_inside_out_whatever_the_scene_name(tmp_path, name, capsys):
    scene_file = tmp_path / "hostile.toml"
    scene_file.write_text(PENDULUM.replace('name = "pendulum"', f'name = "{name}"'))
    out = tmp_path / "deep" / "out"
    before = files_under(tmp_path)
    code = main(["run", str(scene_file), "--t-end", "0.02", "--dt", "0.01", "--out", str(out), "--json"])
    assert code == 0, capsys.readouterr().err
    written = files_under(tmp_path) - before
    assert written and all(p.resolve().is_relative_to(out.resolve()) for p in written), written
    assert {p.parent for p in written} == {out}
    doc = json.loads(capsys.readouterr().out)
    assert all(Path(f).resolve().parent == out.resolve() for f in doc["files"].values() if f)


def test_file_stem_is_a_plain_bounded_name():
    assert file_stem("pendulum") == "pendulum" and file_stem("my-scene_2.v1") == "my-scene_2.v1"
    for bad in ("../../x", "/abs", "a\x00b", "..", "", "x" * 5000, "a/b\\c"):
        stem = file_stem(bad)
        assert stem and "/" not in stem and "\\" not in stem and "\x00" not in stem
        assert not stem.startswith(".") and len(stem) <= MAX_STEM
