"""Scene names are names, not paths: every file ``mslab run`` writes stays inside ``--out`` (issue 37).

One rule (:func:`mslab.files.name_problem`) says which names can become output file names;
``mslab validate`` and ``mslab run`` both read it, so validate refuses exactly what a run
would refuse (in one line naming ``scene.name``, exit 2, before any work), and every name
they accept is sanitised into a stem that stays inside the output folder.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from mslab.cli import main
from mslab.files import MAX_STEM, file_stem, name_problem
from tests.test_hostile import _one_line

PENDULUM = (Path(__file__).parents[1] / "mslab" / "scenes" / "pendulum.toml").read_text()

#: names that cannot become file names, as TOML basic-string bodies (escapes included)
REFUSED = ["../../x", "/tmp/abs_x", "..", ".", "a/../../b", "a\\\\..\\\\b", "nul\\u0000byte", "x" * 5000,
           "line\\nbreak", "", "~/home", "é/ü", ".hidden", "x" * (MAX_STEM + 1)]
#: odd names that are still names: their outputs get a sanitised stem
SANITISED = ["$HOME", "my scene", "é", "a:b*c?", "x" * MAX_STEM, "tab-free_1.5"]


def files_under(root: Path) -> set[Path]:
    return {Path(d, f) for d, _, names in os.walk(root) for f in names}


def hostile_scene(tmp_path: Path, name: str) -> Path:
    scene_file = tmp_path / "hostile.toml"
    scene_file.write_text(PENDULUM.replace('name = "pendulum"', f'name = "{name}"'))
    return scene_file


@pytest.mark.parametrize("name", REFUSED, ids=range(len(REFUSED)))
def test_validate_refuses_what_run_refuses_in_one_line_before_any_work(tmp_path, name, capsys):
    """Fails on the old code: validate said ok (and run sanitised) for every one of these names."""
    scene_file = hostile_scene(tmp_path, name)
    out = tmp_path / "deep" / "out"
    before = files_under(tmp_path)
    seen = _one_line(capsys, ["validate", str(scene_file), "--no-timing"])
    assert seen.startswith(f"mslab: error: {scene_file}: scene.name: "), seen
    assert len(seen) < 300
    ran = _one_line(capsys, ["run", str(scene_file), "--t-end", "0.02", "--dt", "0.01",
                                  "--out", str(out)])
    assert ran == seen  # the same rule, the same line
    assert files_under(tmp_path) == before and not out.exists()


@pytest.mark.parametrize("name", SANITISED, ids=range(len(SANITISED)))
def test_run_writes_only_inside_out_for_every_name_validate_accepts(tmp_path, name, capsys):
    scene_file = hostile_scene(tmp_path, name)
    assert main(["validate", str(scene_file), "--no-timing"]) == 0
    capsys.readouterr()
    out = tmp_path / "deep" / "out"
    before = files_under(tmp_path)
    code = main(["run", str(scene_file), "--t-end", "0.02", "--dt", "0.01", "--out", str(out), "--json"])
    assert code == 0, capsys.readouterr().err
    written = files_under(tmp_path) - before
    assert written and {p.parent for p in written} == {out}, written
    ends = (".npz", "_energy.png", "_final.png")
    assert {p.name for p in written} == {f"{file_stem(name)}{end}" for end in ends}
    doc = json.loads(capsys.readouterr().out)
    assert all(Path(f).resolve().parent == out.resolve() for f in doc["files"].values() if f)


def test_file_stem_is_a_plain_bounded_name_or_a_refusal():
    assert file_stem("pendulum") == "pendulum" and file_stem("my-scene_2.v1") == "my-scene_2.v1"
    assert file_stem("my scene: é") == "my_scene___"
    for bad in ("../../x", "/abs", "a\x00b", "..", ".", "", "x" * 5000, "a/b\\c", "line\nbreak", 3, None):
        assert name_problem(bad)
        with pytest.raises(ValueError, match="scene name"):
            file_stem(bad)


def test_a_default_name_from_the_file_name_follows_the_same_rule(tmp_path, capsys):
    """A scene without ``name`` is named after its file: a hidden file's stem is refused, saying so."""
    scene_file = tmp_path / ".hidden.toml"
    scene_file.write_text(PENDULUM.replace('name = "pendulum"\n', ""))
    line = _one_line(capsys, ["validate", str(scene_file), "--no-timing"])
    assert "scene.name: '.hidden' must not start with '.'" in line and "set [scene] name" in line
