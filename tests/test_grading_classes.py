"""Instructor options, one grader per gradebook, interruptions: refused or explained in one line.

Each test grades one exercise at most (grading spawns processes).
"""

from __future__ import annotations

import fcntl
import os
import shutil
from pathlib import Path

import pytest

from mslab.cli import main as cli_main
from mslab.commands import grade as grade_command
from mslab.grading import grade

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET, MODULE = "07_stability_function", "stability_function.py"


@pytest.fixture
def one_class(tmp_path) -> Path:
    """A class of one: the reference solution of exercise 07."""
    (tmp_path / "class" / "good" / TARGET).mkdir(parents=True)
    shutil.copyfile(SOURCE / TARGET / MODULE, tmp_path / "class" / "good" / TARGET / MODULE)
    return tmp_path / "class"


def _one_line_error(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mslab: error: "), captured.err
    assert "Traceback" not in captured.err
    return lines[0]


@pytest.mark.parametrize("option", [["--timeout", "inf"], ["--timeout", "nan"], ["--timeout", "0"],
                                    ["--timeout", "1e-9"], ["--timeout", "-1"], ["--memory", "0"],
                                    ["--memory", "-1"]])
def test_limits_must_be_positive_finite_numbers(one_class, option, capsys, monkeypatch):
    monkeypatch.setattr(grade_command, "grade", lambda *a, **k: pytest.fail("graded with a bad option"))
    assert cli_main(["grade", str(one_class), "--source", str(SOURCE), "--exercise", TARGET, *option]) == 2
    assert option[0] in _one_line_error(capsys)


def test_csv_must_be_a_regular_file_or_a_new_one(one_class, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(grade_command, "grade", lambda *a, **k: pytest.fail("graded with a bad --csv"))
    for bad in ("/dev/full", str(tmp_path)):
        assert cli_main(["grade", str(one_class), "--source", str(SOURCE), "--csv", bad]) == 2
        assert "--csv" in _one_line_error(capsys)
    assert os.path.exists("/dev/full") and not os.path.isfile("/dev/full")
    link = tmp_path / "link.csv"
    link.symlink_to(tmp_path / "elsewhere.csv")
    assert cli_main(["grade", str(one_class), "--source", str(SOURCE), "--csv", str(link)]) == 2
    assert "--csv" in _one_line_error(capsys)
    assert not (tmp_path / "elsewhere.csv").exists()


def test_a_second_grader_on_one_gradebook_is_refused_and_the_first_resumes(one_class, tmp_path, capsys):
    csv_path, journal = tmp_path / "book.csv", tmp_path / "book.csv.journal"
    journal.write_text('{"first": "line of the first grader"}\n')
    with open(journal, "a") as held:  # the first grader, still grading
        fcntl.flock(held.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert cli_main(["grade", str(one_class), "--source", str(SOURCE), "--exercise", TARGET,
                         "--csv", str(csv_path), "--json"]) == 2
        assert "locked" in _one_line_error(capsys)
        assert journal.read_text() == '{"first": "line of the first grader"}\n'  # untouched, no NUL
        assert not csv_path.exists()
    assert cli_main(["grade", str(one_class), "--source", str(SOURCE), "--exercise", TARGET,
                     "--csv", str(csv_path), "--resume", "--json"]) == 0
    assert csv_path.read_text().splitlines()[1].startswith("good,")
    assert not journal.exists()


def test_two_graders_in_one_process_cannot_share_a_journal(one_class, tmp_path):
    from mslab.grading.report import Journal

    book = Journal(tmp_path / "j", resume=False)
    try:
        with pytest.raises(ValueError, match="locked"):
            grade([one_class], source=SOURCE, only=[TARGET], journal=tmp_path / "j")
    finally:
        book.close(finished=False)


def test_interrupted_grading_names_resume(one_class, tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        kwargs["journal"].add("key", {"entry": None, "why": "x"})
        raise KeyboardInterrupt

    monkeypatch.setattr(grade_command, "grade", interrupted)
    code = cli_main(["grade", str(one_class), "--source", str(SOURCE), "--csv", str(tmp_path / "b.csv")])
    err = capsys.readouterr().err
    assert code != 0
    assert "--resume" in err and str(tmp_path / "b.csv.journal") in err
    assert (tmp_path / "b.csv.journal").read_text().count("\n") == 1  # kept for --resume
