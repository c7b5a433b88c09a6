"""The grader's command line and bookkeeping: isolation modes, journal and --resume, the release.

Each test grades one or two exercises only (grading spawns processes; see test_grading.py
for the whole class of hostile submissions).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from mslab.cli import main as cli_main
from mslab.commands.grade import Progress
from mslab.grading import find_exercises, grade
from mslab.grading.isolation import DESCRIPTION, _probe, unreachable_for_others

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET, MODULE = "07_stability_function", "stability_function.py"
ATTACK = """
import numpy as np
from mslab.stability import amplification

def stability_function(A, b, z):
    return np.asarray(z, dtype=complex)

def real_stability_interval(A, b, tol=1e-12):
    import os
    return float(len(os.listdir("/")))
"""


@pytest.fixture(scope="module")
def small_class(tmp_path_factory) -> Path:
    """A class of two: the reference solution of exercise 07 and an attacker calling mslab."""
    base = tmp_path_factory.mktemp("small")
    for name in ("good", "attacker"):
        (base / "class" / name / TARGET).mkdir(parents=True)
    shutil.copyfile(SOURCE / TARGET / MODULE, base / "class" / "good" / TARGET / MODULE)
    (base / "class" / "attacker" / TARGET / MODULE).write_text(ATTACK)
    return base / "class"


@pytest.mark.skipif(not sys.platform.startswith("linux") or not _probe("namespaces"),
                    reason="no namespaces for the Python jail here (needs root or user namespaces)")
def test_the_python_namespace_path_without_bwrap(small_class):
    results = {r.student: r for r in grade([small_class], source=SOURCE, jobs=1, timeout=10.0,
                                           only=[TARGET], isolation="namespaces")}
    good, bad = results["good"], results["attacker"]
    assert good.isolation == DESCRIPTION["namespaces"]
    assert good.total == good.max_points > 0, [(t.test, t.reason) for e in good.exercises for t in e.tests]
    assert bad.total == 0
    reasons = {t.reason for e in bad.exercises for t in e.tests if t.test.startswith("test_public")}
    assert reasons and all("No module named 'mslab'" in r for r in reasons), reasons


@pytest.mark.skipif(not shutil.which("bwrap") or not _probe("bwrap"), reason="bubblewrap is not installed")
def test_bwrap_path_is_the_default_where_installed(small_class, capsys):
    assert cli_main(["grade", str(small_class / "good"), "--source", str(SOURCE), "--exercise", TARGET]) == 0
    out = capsys.readouterr()
    assert "isolation: isolated by bubblewrap" in out.out and "warning" not in out.err


def test_rlimits_warns_in_one_line_and_require_isolation_refuses(small_class, capsys):
    good = str(small_class / "good")
    assert cli_main(["grade", good, "--source", str(SOURCE), "--exercise", TARGET,
                     "--isolation", "rlimits", "--require-isolation"]) == 2
    assert "isolation required" in capsys.readouterr().err
    if os.geteuid() == 0 and unreachable_for_others():  # as root: a throwaway uid, who must reach Python
        assert cli_main(["grade", good, "--source", str(SOURCE), "--exercise", TARGET,
                         "--isolation", "rlimits"]) == 2
        assert "throwaway user, who cannot reach" in capsys.readouterr().err
        return  # graded in tests/test_grading_rlimits.py, in a view where it can
    assert cli_main(["grade", good, "--source", str(SOURCE), "--exercise", TARGET,
                     "--isolation", "rlimits"]) == 0
    out = capsys.readouterr()
    warnings = [line for line in out.err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and "isolation is rlimits (chosen with --isolation rlimits)" in warnings[0]
    assert "no namespaces on this machine" not in warnings[0]
    assert "NOT isolated" in out.out


def test_source_is_required_outside_the_instructor_tree(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli_main(["grade", str(tmp_path)]) == 2
    assert "--source is required" in capsys.readouterr().err


def test_a_killed_grader_resumes_from_its_journal(small_class, tmp_path):
    """Kill the grader once an item is journaled; --resume grades only the rest."""
    cls = tmp_path / "class"
    shutil.copytree(small_class, cls)
    shutil.copytree(small_class / "good", cls / "third")
    (cls / "third" / "08_penalty_collision").mkdir()
    shutil.copyfile(SOURCE / "08_penalty_collision" / "penalty_collision.py",
                    cls / "third" / "08_penalty_collision" / "penalty_collision.py")
    csv_path, journal = tmp_path / "book.csv", tmp_path / "book.csv.journal"
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "mslab", "grade", str(cls), "--source", str(SOURCE), "--csv", str(csv_path),
           "--exercise", TARGET, "--exercise", "08_penalty_collision", "--jobs", "1"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if journal.exists() and journal.read_text().count("\n") >= 1:
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not csv_path.exists()
    n_done = journal.read_text().count("\n")
    assert n_done >= 1
    seen = []
    saved = tempfile.tempdir
    tempfile.tempdir = str(tmp)
    try:
        results = grade([cls], source=SOURCE, jobs=1, only=[TARGET, "08_penalty_collision"], journal=journal,
                        resume=True, progress=lambda done, total: seen.append(total))
    finally:
        tempfile.tempdir = saved
    assert seen and seen[-1] == 4 - n_done  # 4 items (one student lacks 08): only the rest ran
    scores = {r.student: r.total for r in results}
    maxima = {ex.name: ex.max_points for ex in find_exercises(SOURCE)}
    assert scores["good"] == maxima[TARGET]  # 08 missing from the submission
    assert scores["third"] == maxima[TARGET] + maxima["08_penalty_collision"]
    assert scores["attacker"] == 0
    assert list(tmp.iterdir()) == []  # the killed grader's folders were removed at the next start


def test_csv_is_escaped_and_written_with_the_umask(small_class, tmp_path):
    cls = tmp_path / "class"
    shutil.copytree(small_class / "good", cls / "=cmd|' /C calc'!A0")
    csv_path = tmp_path / "book.csv"
    old = os.umask(0o022)
    try:
        assert cli_main(["grade", str(cls), "--source", str(SOURCE), "--exercise", TARGET,
                         "--csv", str(csv_path), "--json"]) == 0
    finally:
        os.umask(old)
    assert (csv_path.stat().st_mode & 0o777) == 0o644
    assert csv_path.read_text().splitlines()[1].startswith("'=cmd")
    assert not (tmp_path / "book.csv.journal").exists()


def test_release_writes_a_student_readme_and_warns_about_markers(tmp_path, capsys):
    src = tmp_path / "src"
    shutil.copytree(SOURCE, src, ignore=shutil.ignore_patterns("__pycache__"))
    module = src / TARGET / MODULE
    module.write_text(module.read_text() + "\n\ndef extra():\n    ### BEGIN SOLUTION\n    return 42\n")
    (src / TARGET / "notes.txt").write_text("# BEGIN SOLUTION\nthe answer\n# END SOLUTION\n")
    assert cli_main(["release", str(src), str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "marker not understood" in err and "not .py" in err
    readme = (tmp_path / "out" / "README.md").read_text()
    assert "pytest" in readme and "Submit" in readme
    assert "trust boundary" not in readme.lower() and "mslab grade" not in readme and "hidden" in readme


def test_progress_shows_after_two_seconds_only(capsys):
    quiet = Progress(enabled=True)
    quiet(1, 10)
    assert capsys.readouterr().err == ""
    slow = Progress(enabled=True)
    slow.start -= 3.0
    slow(3, 10)
    slow.close()
    assert "grading: 3/10 items" in capsys.readouterr().err
    piped = Progress(enabled=False)
    piped.start -= 3.0
    piped(3, 10)
    assert capsys.readouterr().err == ""


def test_syntax_error_names_its_line_once(tmp_path):
    sub = tmp_path / "student" / TARGET
    sub.mkdir(parents=True)
    (sub / MODULE).write_text("import numpy as np\n\ndef stability_function(A, b, z:\n    pass\n")
    (result,) = grade([tmp_path / "student"], source=SOURCE, jobs=1, only=[TARGET])
    reasons = {t.reason for e in result.exercises for t in e.tests if t.test.startswith("test_public")}
    assert reasons and all(r.count("line 3") == 1 and "SyntaxError" in r for r in reasons), reasons


@pytest.mark.parametrize("euid", [0, 1000])
def test_the_rlimits_warning_names_who_the_student_ran_as(euid, monkeypatch, capsys):
    """Issue 40: as root rlimits runs the student as a throwaway uid (the warning said "your user")."""
    from types import SimpleNamespace

    from mslab.commands.grade import _warn_isolation
    from mslab.grading.isolation import DESCRIPTION

    monkeypatch.setattr("os.geteuid", lambda: euid)
    result = SimpleNamespace(isolation=DESCRIPTION["rlimits"], isolation_asked="rlimits", resources="")
    _warn_isolation(result)
    line = capsys.readouterr().err
    assert line.count("\n") == 1 and "chosen with --isolation rlimits" in line
    assert ("throwaway uid" in line) == (euid == 0) and ("as your user" in line) == (euid != 0)
