"""Which entries are students and what each row is called: every student keeps a row of their own.

Planted from an outside review (flat classes, colliding names, a grader's journal in the
class folder). Only layout and naming here, nothing is graded: no sandbox starts.
"""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import pytest

from mslab.cli import main as cli_main
from mslab.grading import find_exercises
from mslab.grading.autograde import SubmissionResult
from mslab.grading.layout import expand_submissions
from mslab.grading.platforms import canvas_rows

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET, MODULE = "02_euler_steps", "euler_steps.py"
REFERENCE = SOURCE / TARGET / MODULE


@pytest.fixture(scope="module")
def exercises():
    return [e for e in find_exercises(SOURCE) if e.name == TARGET]


def _flat_class(root: Path, files: bool) -> Path:
    """alice and bob, flat: single files, or folders holding the exercise's file itself."""
    root.mkdir()
    for student in ("alice", "bob"):
        if files:
            shutil.copyfile(REFERENCE, root / f"{student}.py")
        else:
            (root / student).mkdir()
            shutil.copyfile(REFERENCE, root / student / MODULE)
    return root


@pytest.mark.parametrize("third", ["loose file", "exercise-named student"])
def test_one_entry_never_makes_a_flat_class_one_submission(tmp_path, exercises, third):
    """A classmate who did not rename, or a student folder named like the exercise: refused, never 1 row."""
    if third == "loose file":
        cls = _flat_class(tmp_path / "class", files=True)
        shutil.copyfile(REFERENCE, cls / MODULE)
    else:
        cls = _flat_class(tmp_path / "class", files=False)
        (cls / TARGET).mkdir()
        shutil.copyfile(REFERENCE, cls / TARGET / MODULE)
    with pytest.raises(ValueError, match="--layout class or --layout submission"):
        expand_submissions([cls], exercises)
    assert len(expand_submissions([cls], exercises, layout="class")) == 3


def test_an_empty_exercise_named_folder_is_one_student_of_the_class(tmp_path, exercises):
    cls = _flat_class(tmp_path / "class", files=False)
    (cls / TARGET).mkdir()
    assert [s.name for s in expand_submissions([cls], exercises)] == [TARGET, "alice", "bob"]


def test_an_ambiguous_class_is_refused_in_one_line_before_grading(tmp_path, capsys):
    cls = _flat_class(tmp_path / "class", files=True)
    shutil.copyfile(REFERENCE, cls / MODULE)
    book = tmp_path / "book.csv"
    code = cli_main(["grade", str(cls), "--source", str(SOURCE), "--exercise", TARGET, "--csv", str(book)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("mslab: error: ") and "--layout" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["class"]  # no gradebook, no journal left


def test_a_single_upload_and_a_released_tree_stay_one_submission(tmp_path, exercises):
    flat = tmp_path / "upload"
    flat.mkdir()
    shutil.copyfile(REFERENCE, flat / MODULE)
    (flat / "README.md").write_text("notes")
    nested = tmp_path / "work"
    (nested / TARGET).mkdir(parents=True)
    shutil.copyfile(REFERENCE, nested / TARGET / MODULE)
    (nested / "conftest.py").write_text("")  # as `mslab release` hands it out
    (nested / "03_heun_midpoint").mkdir()
    for sub in (flat, nested):
        assert [s.path for s in expand_submissions([sub], exercises)] == [sub]


def test_long_and_same_stem_names_get_rows_of_their_own(tmp_path, exercises):
    cls = tmp_path / "class"
    long = "s" * 130
    for student in (f"{long}_good", f"{long}_bad", "bob", "-dash"):
        (cls / student / TARGET).mkdir(parents=True)
        shutil.copyfile(REFERENCE, cls / student / TARGET / MODULE)
    with zipfile.ZipFile(cls / "bob.zip", "w") as zf:
        zf.write(REFERENCE, f"{TARGET}/{MODULE}")
    subs = expand_submissions([cls], exercises)
    names = [s.name for s in subs]
    assert len(set(names)) == len(names) == 5, names
    assert {"bob", "bob.zip", "-dash"} <= set(names)
    assert all(len(n) <= 120 for n in names)
    assert sorted(n[:100] for n in names if n.startswith("s")) == [long[:100]] * 2
    rows = canvas_rows([SubmissionResult(str(s.path), s.name) for s in subs])[2:]
    logins = {row[0]: row[3] for row in rows}
    assert len({row[3] for row in rows if row[3]}) == len([row for row in rows if row[3]])
    assert logins["bob"] == "bob" and logins["bob.zip"] == "bob.zip"
    assert logins["'-dash"] == ""  # never a login that is no one's ("'-dash")


def test_a_graders_journal_in_the_class_folder_is_not_a_student(tmp_path, exercises):
    cls = _flat_class(tmp_path / "class", files=False)
    (cls / "grades.csv.journal").write_text('{"fingerprint": "x"}\n')  # another grader, still grading
    assert [s.name for s in expand_submissions([cls], exercises)] == ["alice", "bob"]
