"""Options the grader cannot honour are refused in one line before grading; the ones it takes, it honours.

Planted from an outside review: a large --memory zeroed every student, the gradebook and
its journal on one path deleted the gradebook, a huge --timeout zeroed every student, and
a one-submission format was refused only after grading a whole class.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from mslab.cli import main as cli_main
from mslab.commands import grade as grade_command

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET, MODULE = "02_euler_steps", "euler_steps.py"


@pytest.fixture
def two(tmp_path) -> Path:
    """A class of two: the reference solution of exercise 02, twice."""
    for student in ("alice", "bob"):
        (tmp_path / "class" / student / TARGET).mkdir(parents=True)
        shutil.copyfile(SOURCE / TARGET / MODULE, tmp_path / "class" / student / TARGET / MODULE)
    return tmp_path / "class"


def _refused(capsys, argv: list[str], *words: str) -> str:
    assert cli_main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mslab: error: "), captured.err
    assert "Traceback" not in captured.err and all(w in lines[0] for w in words), lines[0]
    return lines[0]


def test_more_memory_than_the_runner_had_is_honoured(two, capsys):
    """--memory 8192: above the runner's own 4096 MB, which its sandboxes could not exceed."""
    argv = ["grade", str(two / "alice"), "--source", str(SOURCE), "--exercise", TARGET, "--memory", "8192",
            "--json"]
    assert cli_main(argv) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["total"] == doc["max"] > 0, doc


@pytest.mark.parametrize("option", [["--timeout", "1e12"], ["--timeout", "86401"],
                                    ["--memory", str(10**30)], ["--memory", str((1 << 20) + 1)],
                                    ["--jobs", "100000"]])
def test_limits_beyond_what_the_grader_can_honour_are_refused(two, option, capsys, monkeypatch):
    monkeypatch.setattr(grade_command, "grade", lambda *a, **k: pytest.fail("graded with a bad option"))
    _refused(capsys, ["grade", str(two), "--source", str(SOURCE), "--exercise", TARGET, *option], option[0])


def test_an_output_on_another_outputs_path_is_refused_before_grading(two, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(grade_command, "grade", lambda *a, **k: pytest.fail("graded with clashing outputs"))
    book = tmp_path / "book.csv"
    base = ["grade", str(two), "--source", str(SOURCE), "--exercise", TARGET]
    _refused(capsys, [*base, "--csv", str(book), "--journal", str(book)], "--journal", "--csv")
    _refused(capsys, [*base, "--csv", str(book), "--journal", str(tmp_path / "." / "book.csv")], "--journal")
    assert not book.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["class"]
    flat = two / "carol.py"
    flat.write_text("x = 1\n")
    _refused(capsys, [*base, "--csv", str(flat)], "--csv")
    assert flat.read_text() == "x = 1\n"


@pytest.mark.parametrize("fmt", ["gradescope", "prairielearn"])
def test_a_one_submission_format_on_a_class_is_refused_before_grading(two, tmp_path, fmt, capsys,
                                                                      monkeypatch):
    monkeypatch.setattr(grade_command, "grade", lambda *a, **k: pytest.fail("graded a class for " + fmt))
    out = tmp_path / "results.json"
    _refused(capsys, ["grade", str(two), "--source", str(SOURCE), "--exercise", TARGET, "--format", fmt,
                      "--output", str(out)], "--format", "2 submissions")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["class"]  # no results.json, no journal


def test_a_grading_the_grader_itself_failed_is_no_class_of_zeros(two, tmp_path, capsys, monkeypatch):
    """The runner's old fixed 4096 MB again: no sandbox can start, and that is said, not graded 0."""
    from mslab.grading import dispatch

    monkeypatch.setattr(dispatch, "runner_memory_mb", lambda sandbox_mb: 4096, raising=False)
    book = tmp_path / "book.csv"
    line = _refused(capsys, ["grade", str(two), "--source", str(SOURCE), "--exercise", TARGET,
                             "--memory", "8192", "--csv", str(book), "--jobs", "1"], "grader's own")
    assert "could not start the sandbox" in line or "hidden test: the grader failed" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["class"]  # no gradebook, no journal to resume


def test_a_platform_upload_with_other_files_is_still_one_submission(tmp_path):
    """Gradescope's upload folder is one submission: a scratch file beside the answer is not a classmate."""
    from mslab.commands.platform_entry import entry

    source = tmp_path / "source"
    shutil.copytree(SOURCE / TARGET, source / TARGET)
    upload = tmp_path / "submission"
    upload.mkdir()
    shutil.copyfile(SOURCE / TARGET / MODULE, upload / MODULE)
    (upload / "scratch.py").write_text("print('trying things')\n")
    out = tmp_path / "results" / "results.json"
    assert entry(["gradescope", str(upload), str(source), str(out), "--isolation", "auto", TARGET]) == 0
    doc = json.loads(out.read_text())
    assert doc["score"] == sum(t["max_score"] for t in doc["tests"]) > 0, doc


def test_some_tests_the_grader_failed_are_reported_and_the_class_still_graded(capsys):
    """A sandbox that could not start after others ran (a student may have caused it) never stops the
    class's grading: the gradebook is written and one warning names those tests; only a grading whose
    every test the grader failed is refused."""
    from mslab.commands.common import CommandError
    from mslab.commands.grade import _refuse_grader_faults
    from mslab.grading.autograde import ExerciseResult, SubmissionResult, TestResult

    def student(name: str, fault: bool) -> SubmissionResult:
        test = TestResult("test_step", 0.0 if fault else 1.0, 1.0, not fault,
                          "the grader failed" if fault else "", grader_fault=fault)
        return SubmissionResult(name, name, [ExerciseResult(TARGET, [test])])

    _refuse_grader_faults([student("ann", False), student("bob", True)], None)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mslab: warning: 1 test(s)") and "bob: test_step" in err[0]
    with pytest.raises(CommandError, match="2 test"):
        _refuse_grader_faults([student("ann", True), student("bob", True)], None)
