"""Instructor options, one grader per gradebook, interruptions: refused or explained in one line.

Each test grades one exercise at most (grading spawns processes).
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
from test_grading import _processes_with
from test_grading_trust import _honest_source
from test_grading_zips import lzma_zip

from mslab.cli import main as cli_main
from mslab.commands import grade as grade_command
from mslab.grading import autograde, find_exercises, grade
from mslab.grading.dispatch import run_runner
from mslab.grading.intake import Submission
from mslab.grading.isolation import detect, unreachable_for_others
from mslab.grading.layout import expand_submissions, read_student_file

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


# -- classes as courses hand them in ----------------------------------------------------------------

def _notebook(code: str) -> str:
    cells = [{"cell_type": "markdown", "metadata": {}, "source": ["# my answer"]},
             {"cell_type": "code", "metadata": {}, "execution_count": 1, "outputs": [],
              "source": ["%matplotlib inline\n", *code.splitlines(keepends=True)]}]
    return json.dumps({"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5})


@pytest.fixture(scope="module")
def handed_in(tmp_path_factory) -> Path:
    """A class as a course collects it: folders, zips, a notebook, a student named like an exercise."""
    cls = tmp_path_factory.mktemp("handed") / "class"
    reference = (SOURCE / TARGET / MODULE).read_text()
    for student in ("alice", TARGET, ".dave"):
        (cls / student / TARGET).mkdir(parents=True)
        (cls / student / TARGET / MODULE).write_text(reference)
    with zipfile.ZipFile(cls / "bob.zip", "w") as zf:
        zf.writestr(f"bob/{TARGET}/{MODULE}", reference)
    with zipfile.ZipFile(cls / "mallory.zip", "w") as zf:  # a member outside its folder
        zf.writestr(f"../../{MODULE}", reference)
    with zipfile.ZipFile(cls / "trudy.zip", "w", zipfile.ZIP_DEFLATED) as zf:  # a bomb
        for k in range(6):
            zf.writestr(f"{TARGET}/pad{k}.py", b"0" * 10_000_000)
    # the reference, but decoding it first allocates a 4 GB dictionary: beyond the sandbox's 1024 MB
    (cls / "eve.zip").write_bytes(lzma_zip(f"eve/{TARGET}/{MODULE}", reference.encode()))
    for k in (1, 2):  # honest variations of the reference (a batched solve, a counted bisection)
        (cls / f"variant{k}" / TARGET).mkdir(parents=True)
        (cls / f"variant{k}" / TARGET / MODULE).write_text(_honest_source(k))
    (cls / "carol.ipynb").write_text(_notebook(reference))
    (cls / "notes.txt").write_text("not a submission")
    return cls


@pytest.fixture(scope="module")
def handed_in_graded(handed_in) -> dict:
    return {r.student: r for r in grade([handed_in], source=SOURCE, jobs=1, only=[TARGET])}


def test_every_entry_of_a_class_gets_a_row(handed_in_graded):
    assert sorted(handed_in_graded) == sorted([".dave", TARGET, "alice", "bob", "carol", "mallory",
                                               "notes.txt", "trudy", "eve", "variant1", "variant2"])


def test_folders_zips_notebooks_and_exercise_named_students_are_graded(handed_in_graded):
    for name in ("alice", TARGET, "bob", "carol", "variant1", "variant2"):
        r = handed_in_graded[name]
        assert r.total == r.max_points > 0, (name, [t.reason for e in r.exercises for t in e.tests])


def test_what_cannot_be_graded_says_why(handed_in_graded):
    names = (".dave", "notes.txt", "mallory", "trudy", "eve")
    reasons = {name: handed_in_graded[name].exercises[0].errors for name in names}
    assert "hidden entry" in reasons[".dave"][0]
    assert "not a folder, .zip, .py or .ipynb" in reasons["notes.txt"][0]
    assert "mallory.zip: member '../../" in reasons["mallory"][0] and "'..'" in reasons["mallory"][0]
    assert "trudy.zip: unpacks to more than 50000000 bytes" in reasons["trudy"][0]
    assert all(handed_in_graded[n].total == 0 for n in reasons)


def test_a_zip_is_decompressed_within_the_sandbox_memory(handed_in_graded):
    """eve.zip holds the reference; decoding it needs 4 GB: the grader, unlimited, would have graded it
    (full marks); the sandbox that unpacks it has the grading's 1024 MB and refuses it, saying so."""
    (reason,) = handed_in_graded["eve"].exercises[0].errors
    assert reason == "eve.zip: ran out of memory while unpacking (the sandbox's limit of 1024 MB)"
    assert handed_in_graded["eve"].total == 0


def test_layout_rule_and_flag(handed_in, tmp_path):
    exercises = [e for e in find_exercises(SOURCE) if e.name == TARGET]
    assert len(expand_submissions([handed_in], exercises)) == 11
    one = expand_submissions([handed_in], exercises, layout="submission")
    assert [s.path for s in one] == [handed_in]
    inner = expand_submissions([handed_in / "alice"], exercises)  # a submission: its file decides
    assert [s.name for s in inner] == ["alice"]
    ambiguous = tmp_path / "ambiguous"
    shutil.copytree(handed_in / "alice", ambiguous)
    shutil.copytree(handed_in / "alice", ambiguous / "eve")
    with pytest.raises(ValueError, match="--layout"):
        expand_submissions([ambiguous], exercises)
    assert [s.name for s in expand_submissions([ambiguous], exercises, layout="class")] == [TARGET, "eve"]


def test_a_flat_upload_is_graded_as_the_exercise(tmp_path, capsys):
    flat = tmp_path / "submission"
    flat.mkdir()
    shutil.copyfile(SOURCE / TARGET / MODULE, flat / MODULE)
    assert cli_main(["grade", str(flat), "--source", str(SOURCE), "--exercise", TARGET, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["total"] == doc["max"] > 0, doc


def test_a_file_swapped_for_a_link_is_never_followed(tmp_path):
    sub = tmp_path / "sub"
    (sub / TARGET).mkdir(parents=True)
    (sub / TARGET / MODULE).symlink_to(SOURCE / TARGET / MODULE)
    ex = next(e for e in find_exercises(SOURCE) if e.name == TARGET)
    text, why = read_student_file(Submission(sub, "sub"), ex)
    assert text is None and "symbolic link" in why
    (sub / TARGET / MODULE).unlink()
    os.rmdir(sub / TARGET)
    (sub / TARGET).symlink_to(SOURCE / TARGET)
    text, why = read_student_file(Submission(sub, "sub"), ex)
    assert text is None and "symbolic link" in why


# -- graders side by side ---------------------------------------------------------------------------

#: the mark in the command line of the first grader's holder
HOLD = "mslab-hold-first-grader"


@pytest.mark.skipif(os.geteuid() != 0 or not shutil.which("unshare"),
                    reason="needs root and unshare to start the second grader in a PID namespace of its own")
def test_two_graders_in_two_pid_namespaces_over_one_temporary_folder(tmp_path):
    """The second grader's clean-up, blind to the first one's PIDs, removes nothing of it."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    first, second = tmp_path / "first", tmp_path / "second"
    for cls in (first, second):
        (cls / "b_honest" / TARGET).mkdir(parents=True)
        shutil.copyfile(SOURCE / TARGET / MODULE, cls / "b_honest" / TARGET / MODULE)
    # holds the first runner while the second grader runs: its import waits (no CPU) for a marked
    # child of its own, which the test ends once the second grader is done
    (first / "a_holder" / TARGET).mkdir(parents=True)
    (first / "a_holder" / TARGET / MODULE).write_text(
        "import subprocess, sys\n"
        f"code = 'import sys; sys.stdin.read() # {HOLD}'\n"
        "subprocess.Popen([sys.executable, '-c', code], stdin=subprocess.PIPE).wait()\n"
        "raise RuntimeError('held')\n")
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "mslab", "grade", "--source", str(SOURCE), "--exercise", TARGET,
           "--jobs", "1", "--json"]
    proc = subprocess.Popen([*cmd, str(first)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline = time.monotonic() + 120
        while not _processes_with(HOLD) and proc.poll() is None:
            assert time.monotonic() < deadline, "the first grader's runner did not start its student"
            time.sleep(0.05)  # waits for a condition, not a duration
        assert list(tmp.glob("mslab-grade-*/runner-*")), "the first grader has no runner folder"
        other = subprocess.run(["unshare", "--pid", "--fork", *cmd, str(second)], env=env,
                               capture_output=True, text=True, timeout=300)
        assert proc.poll() is None and _processes_with(HOLD), "the first grader ended: this proved nothing"
        while proc.poll() is None:  # release the holder (once per sandbox it starts)
            for pid in _processes_with(HOLD):
                os.kill(pid, signal.SIGKILL)
            time.sleep(0.05)  # waits for a condition, not a duration
        out, err = proc.communicate(timeout=600)
    finally:
        proc.kill()
        for pid in _processes_with(HOLD):
            os.kill(pid, signal.SIGKILL)
    assert other.returncode == 0, other.stderr[-2000:]
    assert json.loads(other.stdout)["total"] == json.loads(other.stdout)["max"] > 0
    assert proc.returncode == 0, err[-2000:]
    results = {d["student"]: d for d in json.loads(out)["submissions"]}
    assert results["b_honest"]["total"] == results["b_honest"]["max"] > 0, results["b_honest"]
    assert results["a_holder"]["total"] == 0
    assert list(tmp.iterdir()) == []  # nothing left by either


# -- wall time per submission -----------------------------------------------------------------------

def test_a_sleeper_costs_its_own_wall_budget_once(tmp_path, monkeypatch):
    """The runner is stopped at the sleeping item's own budget; the item is not re-run, the next one is."""
    ex = next(e for e in find_exercises(SOURCE) if e.name == TARGET)
    home = tmp_path / "home"
    home.mkdir()

    def item(key: str, text: str) -> dict:
        return {"key": key, "name": ex.name, "module": ex.module, "student_source": text, "tests": ex.tests,
                "n_tests": len(ex.points), "cpu_s": 60}

    sleeper = item("sleeper", "import time\ntime.sleep(10 ** 6)\n")
    honest = item("honest", (SOURCE / TARGET / MODULE).read_text())
    mode = detect("auto")
    if mode == "rlimits" and os.geteuid() == 0 and unreachable_for_others():
        pytest.skip("no isolation mode can start a sandbox here")
    job = {"nonce": "ab" * 16, "timeout": 10.0, "memory_mb": 1024, "isolation": mode,
           "import_timeout": 30.0, "cgroups": None, "home": str(home), "items": [sleeper, honest]}
    done, why, overran = run_runner(job, [3.0, 600.0], lambda k, o: None)
    assert (done, overran) == (set(), "sleeper")
    assert "wall-clock limit of 3 s for one exercise of one submission" in why
    assert list(home.iterdir()) == []

    calls, seen = [], {}

    def fake_run_items(items, ctx, on_item):  # the runner stopped at the sleeper's budget
        calls.append([it["key"] for it in items])
        if items[0]["key"] == "sleeper":
            return set(), why, "sleeper"
        for it in items:
            on_item(it["key"], {"results": {}, "errors": []})
        return {it["key"] for it in items}, "", ""

    monkeypatch.setattr(autograde, "_run_items", fake_run_items)
    autograde._run_chunk([sleeper, honest], {}, lambda k, o, w: seen.setdefault(k, (o, w)))
    assert calls == [["sleeper", "honest"], ["honest"]]  # never the sleeper alone a second time
    assert seen["sleeper"] == (None, why) and seen["honest"][0] is not None
