"""Graded exercises: the release, the autograder, and every hostile submission.

Grading spawns processes (a runner per exercise and submission, a sandbox inside it), so
the expensive runs happen once per module in fixtures and the tests read their results:
the reference solutions and the untouched release in one grading run, a class of hostile
submissions (all aimed at one exercise) in another.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import textwrap
from pathlib import Path

import numpy as np
import pytest

from mslab.cli import main as cli_main
from mslab.grading import (
    find_exercises,
    format_report,
    grade,
    gradebook_rows,
    solution_lines,
    strip_solutions,
)
from mslab.grading.isolation import detect
from mslab.grading.layout import BEGIN, END
from mslab.grading.problems import problem
from mslab.grading.wire import WireError, dumps, loads

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET = "07_stability_function"   # the exercise the hostile class attacks
MODULE = "stability_function.py"
TIMEOUT = 2.0
#: where a .pth file would patch every later run of the grader's interpreter
SITE_PTH = Path(sysconfig.get_paths()["purelib"]) / "zz_mslab_redteam.pth"
ISOLATED = detect() != "rlimits"
needs_isolation = pytest.mark.skipif(not ISOLATED, reason="no namespaces here (no bwrap, no user namespaces)")


# -- release ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def released(tmp_path_factory) -> Path:
    """A release of a copy of the source tree that also holds byte-code and caches."""
    base = tmp_path_factory.mktemp("release")
    src = base / "src"
    shutil.copytree(SOURCE, src, ignore=shutil.ignore_patterns("__pycache__", ".pytest_cache"))
    first = sorted(p for p in src.iterdir() if p.is_dir())[0]
    (first / "__pycache__").mkdir()
    (first / "__pycache__" / "spring_force.cpython-311.pyc").write_bytes(b"solution bytes")
    (src / ".pytest_cache").mkdir()
    (src / ".pytest_cache" / "v").write_text("cache")
    (first / "stray.pyc").write_bytes(b"more solution bytes")
    dest = base / "student"
    assert cli_main(["release", str(src), str(dest)]) == 0
    return dest


def test_twelve_exercises_each_with_text_source_and_tests():
    exercises = find_exercises(SOURCE)
    assert len(exercises) == 12
    for ex in exercises:
        assert (ex.folder / "README.md").is_file(), ex.name
        assert set(ex.tests) - {"expected.json"} == {"test_public.py", "test_hidden.py"}, ex.name
        # the public tests' stored answers travel with them (exercise 02's tests need none)
        assert ("expected.json" in ex.tests) == ("Expected(" in ex.tests["test_public.py"]), ex.name
        public = [k for k in ex.points if k.startswith("test_public")]
        hidden = [k for k in ex.points if k.startswith("test_hidden")]
        assert len(public) >= 3 and len(hidden) >= 3, ex.name
        assert all(p >= 1 for p in ex.points.values())


def test_no_solution_line_survives_the_release(released):
    released_lines = set()
    for path in released.rglob("*"):
        if path.is_file():
            released_lines.update(line.strip() for line in path.read_text(errors="replace").splitlines())
    n_checked = 0
    for ex in find_exercises(SOURCE):
        for line in solution_lines((ex.folder / ex.module).read_text()):
            assert line not in released_lines, f"{ex.name}: solution line released: {line!r}"
            n_checked += 1
    assert n_checked > 50


def test_release_leaves_out_hidden_tests_markers_and_caches(released):
    files = sorted(p.relative_to(released).as_posix() for p in released.rglob("*") if p.is_file())
    assert not [f for f in files if "hidden" in f or f.endswith(".pyc") or "cache" in f]
    for ex in find_exercises(SOURCE):
        text = (released / ex.name / ex.module).read_text()
        assert BEGIN not in text and END not in text
        assert "raise NotImplementedError" in text
        assert (released / ex.name / "test_public.py").read_text() == ex.tests["test_public.py"]
        assert (released / ex.name / "README.md").is_file()
    assert (released / "README.md").is_file() and (released / "conftest.py").is_file()


def test_strip_keeps_indentation_and_rejects_broken_markers():
    src = "def f(x):\n    '''doc'''\n    # BEGIN SOLUTION\n    return 2 * x\n    # END SOLUTION\n"
    assert strip_solutions(src) == "def f(x):\n    '''doc'''\n    raise NotImplementedError\n"
    with pytest.raises(ValueError, match="never closed"):
        strip_solutions("def f():\n    # BEGIN SOLUTION\n    return 1\n")
    with pytest.raises(ValueError, match="without"):
        strip_solutions("x = 1\n# END SOLUTION\n")


def test_release_refuses_a_target_inside_the_source(tmp_path, capsys):
    assert cli_main(["release", str(SOURCE), str(SOURCE / "out")]) == 2
    assert "outside the source" in capsys.readouterr().err


def test_public_tests_run_locally_on_the_release(released, tmp_path):
    """The student's workflow: plain pytest in the released folder."""
    work = tmp_path / "work"
    shutil.copytree(released, work)
    shutil.copyfile(SOURCE / TARGET / MODULE, work / TARGET / MODULE)  # one exercise solved
    other = "08_penalty_collision"  # one exercise solved, one untouched
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", str(work / TARGET), str(work / other)],
                          capture_output=True, text=True, cwd=work, timeout=300,
                          env=dict(os.environ, PYTEST_ADDOPTS="", PYTEST_DISABLE_PLUGIN_AUTOLOAD="1"))
    publics = {ex.name: sum(k.startswith("test_public") for k in ex.points) for ex in find_exercises(SOURCE)}
    assert f"{publics[other]} failed, {publics[TARGET]} passed" in proc.stdout, proc.stdout[-2000:]


# -- grading: reference solutions, the untouched release, the gradebook: tests/test_grading_trivial.py


def test_grade_reports_clear_errors(tmp_path, capsys):
    assert cli_main(["grade", str(tmp_path / "nowhere")]) == 2
    assert "no such folder" in capsys.readouterr().err
    assert cli_main(["grade", str(SOURCE), "--timeout", "0"]) == 2


# -- hostile submissions ----------------------------------------------------------------------

SOLUTION = (SOURCE / TARGET / MODULE).read_text()

HOSTILE = {
    "empty": None,  # the untouched release of the exercise
    "infinite_loop": """
        def stability_function(A, b, z):
            while True:
                pass

        def real_stability_interval(A, b, tol=1e-12):
            raise NotImplementedError
    """,
    "exception": """
        def stability_function(A, b, z):
            raise ValueError("boom")

        def real_stability_interval(A, b, tol=1e-12):
            return 1 / 0
    """,
    "syntax_error": """
        def stability_function(A, b, z)
            return z
    """,
    "missing_function": """
        def something_else():
            return 1
    """,
    "wrong_shape_dtype": """
        import numpy as np

        def stability_function(A, b, z):
            return np.zeros(3, dtype=np.int64)

        def real_stability_interval(A, b, tol=1e-12):
            return "-2"
    """,
    "not_data": """
        def stability_function(A, b, z):
            return lambda: 1

        def real_stability_interval(A, b, tol=1e-12):
            return object()
    """,
    "memory_hog": """
        import numpy as np

        def stability_function(A, b, z):
            return np.ones(10**10)

        def real_stability_interval(A, b, tol=1e-12):
            return float(np.ones(10**10).sum())
    """,
    "exit_at_import": """
        import sys
        sys.exit(0)
    """,
    "hard_exit_at_import": """
        import os
        os._exit(0)
    """,
    "patch_pytest_and_helpers": """
        import numpy as np
        import numpy.testing
        import pytest
        import mslab.grading.checks as checks

        pytest.approx = lambda *a, **k: True
        numpy.testing.assert_allclose = lambda *a, **k: None
        for name in dir(checks):
            if name.startswith("check"):
                setattr(checks, name, lambda *a, **k: None)

        def stability_function(A, b, z):
            return np.zeros(np.shape(z), dtype=complex)

        def real_stability_interval(A, b, tol=1e-12):
            return 0.0
    """,
    "forge_results": """
        import json, os, sys
        from pathlib import Path

        fake = {"results": {"test_public.py::" + n: {"passed": True, "reason": "ok"}
                            for n in ("a", "b")}, "errors": []}
        line = "0" * 32 + " " + json.dumps(fake) + "\\n"
        print("===== 6 passed in 0.01s =====")
        print(line)
        sys.stdout.flush()
        opened = []
        try:
            fds = list((Path("/proc") / str(os.getppid()) / "fd").iterdir())
        except OSError:
            fds = []
        for d in fds:
            try:
                with open(d, "w") as fh:
                    fh.write(line)
                opened.append(d.name)
            except OSError:
                pass
        Path(MARKER).write_text(json.dumps(opened))
        for fd in range(3, 64):
            try:
                os.write(fd, line.encode())
            except OSError:
                pass
        for folder in (Path.cwd(), Path.cwd().parent, Path.cwd().parent.parent):
            for name in ("result.json", "results.json", "report.json", ".grade.json"):
                try:
                    (folder / name).write_text(json.dumps(fake))
                except OSError:
                    pass

        def stability_function(A, b, z):
            return None

        def real_stability_interval(A, b, tol=1e-12):
            return None
    """,
    "kill_runner": """
        import os
        import signal

        os.kill(os.getppid(), signal.SIGKILL)
    """,
    # -- the red team of issue 10 -------------------------------------------------------------
    "import_mslab": """
        import numpy as np
        from mslab.stability import amplification, real_interval
        from mslab.integrators import ExplicitRK

        def stability_function(A, b, z):
            return np.asarray(amplification(ExplicitRK(A, b), z), dtype=complex)

        def real_stability_interval(A, b, tol=1e-12):
            return float(real_interval(ExplicitRK(A, b)))
    """,
    "load_reference": """
        import glob, os, sys
        found = {}
        guesses = [REFERENCE] + glob.glob("/proc/*/cmdline")
        for path in guesses:
            try:
                text = open(path, "rb").read().decode(errors="replace")
            except OSError:
                continue
            if path.endswith("cmdline"):
                for word in text.split("\0"):
                    for cand in glob.glob(os.path.join(word, "**", "stability_function.py"), recursive=True):
                        guesses.append(cand)
                continue
            exec(compile(text, path, "exec"), found)
            break
        stability_function = found.get("stability_function")
        real_stability_interval = found.get("real_stability_interval")
    """,
    "read_classmate": """
        found = {}
        try:
            exec(open(CLASSMATE).read(), found)
        except OSError:
            pass
        stability_function = found.get("stability_function")
        real_stability_interval = found.get("real_stability_interval")
    """,
    "daemons_and_files": """
        import os, subprocess, sys
        NL = chr(10)
        lines = ["# mslab-redteam-daemon", "import time",
                 "for _ in range(600):",
                 "    for p in (CSV, REFERENCE, SITE_PTH):",
                 "        try:",
                 "            open(p, 'a').write('hacked')",
                 "        except OSError:",
                 "            pass",
                 "    time.sleep(0.05)"]
        code = NL.join(lines).replace("CSV", repr(CSV)).replace("REFERENCE", repr(REFERENCE))
        code = code.replace("SITE_PTH", repr(SITE_PTH))
        for _ in range(100):
            try:
                subprocess.Popen([sys.executable, "-c", code], start_new_session=True,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            except OSError:
                break
        for k in range(200):  # 200 MB of files, wherever they may go
            for folder in (".", "/tmp", os.path.dirname(CSV)):
                try:
                    with open(os.path.join(folder, f"junk{k}"), "wb") as fh:
                        fh.write(b"x" * 1_000_000)
                except OSError:
                    pass

        def stability_function(A, b, z):
            raise NotImplementedError

        def real_stability_interval(A, b, tol=1e-12):
            raise NotImplementedError
    """,
    "huge_reply": """
        def stability_function(A, b, z):
            return [[] for _ in range(10_000_000)]

        def real_stability_interval(A, b, tol=1e-12):
            return [[] for _ in range(10_000_000)]
    """,
    "edit_tests": """
        import os
        from pathlib import Path

        PASS = "import pytest\\n\\n@pytest.mark.points(100)\\ndef test_free():\\n    pass\\n"
        here = Path.cwd()
        for top in (here.parent, here.parent.parent):
            for path in top.rglob("test_*.py"):
                try:
                    os.chmod(path, 0o644)
                    os.chmod(path.parent, 0o755)
                    path.write_text(PASS)
                except OSError:
                    pass

        def stability_function(A, b, z):
            raise NotImplementedError

        def real_stability_interval(A, b, tol=1e-12):
            raise NotImplementedError
    """,
}

#: cases that, unisolated, would write outside their folder (run only where namespaces exist)
RISKY = {"daemons_and_files", "load_reference", "read_classmate", "import_mslab"}

#: what the report must say for each hostile case (a piece of the reason of every test)
REASONS = {
    "empty": "NotImplementedError",
    "infinite_loop": None,   # checked in its own test
    "exception": None,
    "syntax_error": "SyntaxError",
    "missing_function": "missing function",
    "wrong_shape_dtype": None,
    "not_data": "not plain data",
    "memory_hog": "MemoryError",
    "exit_at_import": "sys.exit(0)",
    "hard_exit_at_import": "exited with code 0 while importing",
    "patch_pytest_and_helpers": None,
    "forge_results": None,
    "edit_tests": "NotImplementedError",
    "kill_runner": None,  # isolated: the runner is out of sight; else: "test runner stopped"
    "import_mslab": "No module named 'mslab'",
    "load_reference": None,
    "read_classmate": None,
    "daemons_and_files": None,
    "huge_reply": None,
}
#: the fixed phrase a hidden test of each case shows instead (nothing of the sandbox's text)
NO_IMPORT = "the module could not be imported"
RAISED = "raised an exception"
HIDDEN_PHRASE = {"empty": RAISED, "syntax_error": NO_IMPORT, "missing_function": "missing function",
                 "not_data": "answered something that is not plain data", "memory_hog": RAISED,
                 "exit_at_import": NO_IMPORT, "hard_exit_at_import": "the process died", "edit_tests": RAISED,
                 "import_mslab": NO_IMPORT}


@pytest.fixture(scope="module")
def hostile(released, tmp_path_factory):
    """Grade a class of hostile submissions (all aimed at exercise 07) in one run."""
    base = tmp_path_factory.mktemp("hostile")
    cls = base / "class"
    marker = base / "proc_fd_marker.json"
    reference = base / "reference_copy.py"  # attacks aim at a copy, never at the source tree
    reference.write_text(SOLUTION)
    paths = {"MARKER": marker, "REFERENCE": reference, "CSV": base / "gradebook.csv",
             "CLASSMATE": cls / "victim" / TARGET / MODULE, "SITE_PTH": SITE_PTH}
    (base / "gradebook.csv").write_text("student,total\n")
    for student, source in HOSTILE.items():
        if student in RISKY and not ISOLATED:
            continue  # without namespaces these would really write into the grader's venv
        folder = cls / student
        shutil.copytree(released, folder)
        if source is not None:
            text = textwrap.dedent(source)
            for name, value in paths.items():
                text = text.replace(name, repr(str(value)))
            (folder / TARGET / MODULE).write_text(text)
    # a classmate with the perfect solution, graded by the same runners
    shutil.copytree(released, cls / "victim")
    shutil.copyfile(SOURCE / TARGET / MODULE, cls / "victim" / TARGET / MODULE)
    # a hard link to (a copy of) the reference, and a submission folder that is a symbolic link
    shutil.copytree(released, cls / "hard_link")
    (base / "copy.py").write_text(SOLUTION)
    (cls / "hard_link" / TARGET / MODULE).unlink()
    os.link(base / "copy.py", cls / "hard_link" / TARGET / MODULE)
    shutil.copytree(cls / "victim", base / "elsewhere")
    (cls / "symlinked_folder").symlink_to(base / "elsewhere")
    # names a spreadsheet would run, or that forge a summary line
    for evil in ('=HYPERLINK("evil.example","x")', "forged\nvictim 98"):
        shutil.copytree(released, cls / evil)
    # the test editor also ships its own, always-passing tests and conftest
    for name in ("test_public.py", "test_hidden.py", "conftest.py"):
        (cls / "edit_tests" / TARGET / name).write_text(
            "import pytest\n\n@pytest.mark.points(100)\ndef test_free():\n    pass\n")
    # a submission whose file links to the reference solution
    link = cls / "symlink" / TARGET / MODULE
    shutil.copytree(released, cls / "symlink")
    link.unlink()
    link.symlink_to(SOURCE / TARGET / MODULE)
    # a correct submission that prints megabytes (printing costs time, never the grade)
    chatty = cls / "chatty_but_correct"
    shutil.copytree(released, chatty)
    begin = '    """\n    # BEGIN SOLUTION'
    noisy = SOLUTION.replace(begin, '    """\n    print("z" * 1_000_000)\n    # BEGIN SOLUTION', 1)
    assert noisy != SOLUTION
    (chatty / TARGET / MODULE).write_text(
        "import sys\nsys.stdout.write('x' * 20_000_000)\nsys.stderr.write('y' * 5_000_000)\n" + noisy)
    tmp = base / "tmp"
    tmp.mkdir()
    saved, saved_dir = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"] = tempfile.tempdir = str(tmp)  # every grader and runner folder goes here
    try:
        results = grade([cls], source=SOURCE, jobs=2, timeout=TIMEOUT, only=[TARGET])
    finally:
        tempfile.tempdir = saved_dir
        if saved is None:
            del os.environ["TMPDIR"]
        else:
            os.environ["TMPDIR"] = saved
    return {r.submission.split(os.sep)[-1]: r for r in results}, marker, base


def outcomes_of(result):
    (ex,) = result.exercises
    return ex.tests


def _processes_with(tag: str) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if tag.encode() in (entry / "cmdline").read_bytes():
                    found.append(int(entry.name))
            except OSError:
                pass
    return found


def test_hostile_submissions_score_no_more_than_an_empty_one(hostile):
    results = hostile[0]
    empty = results["empty"].total
    assert empty == 0
    for name in [n for n in HOSTILE if n in results] + ["hard_link", "symlinked_folder"]:
        assert results[name].total <= empty, (name, [(t.test, t.reason) for t in outcomes_of(results[name])])
        assert results[name].max_points == results["empty"].max_points


def test_the_victim_keeps_full_marks(hostile):
    victim = hostile[0]["victim"]
    assert victim.total == victim.max_points > 0, [(t.test, t.reason) for t in outcomes_of(victim)]


@needs_isolation
def test_nothing_outlives_grading_and_nothing_is_left_behind(hostile):
    _, _, base = hostile
    assert _processes_with("mslab-redteam-daemon") == []
    assert list((base / "tmp").iterdir()) == []  # no runner folder, no hidden test, no student file
    assert not list(base.glob("junk*"))
    assert (base / "gradebook.csv").read_text() == "student,total\n"
    assert (base / "reference_copy.py").read_text() == SOLUTION
    assert not SITE_PTH.exists()


@needs_isolation
def test_the_sandbox_cannot_import_mslab_nor_read_the_source(hostile):
    results = hostile[0]
    assert all("No module named 'mslab'" in t.reason for t in outcomes_of(results["import_mslab"])
               if t.test.startswith("test_public"))
    for name in ("load_reference", "read_classmate"):  # nothing to find: whatever they do fails
        assert results[name].total == 0 and not any(t.passed for t in outcomes_of(results[name])), name


def test_plain_files_only(hostile):
    results = hostile[0]
    assert all("hard links" in t.reason for t in outcomes_of(results["hard_link"]))
    assert all("symbolic link" in t.reason for t in outcomes_of(results["symlinked_folder"]))


def test_a_huge_reply_is_refused_not_decoded(hostile):
    reasons = [t.reason for t in outcomes_of(hostile[0]["huge_reply"])]
    assert all("not data" in r or "answered more than" in r or "hidden test" in r or "timed out" in r
               for r in reasons), reasons
    # the decoder refuses ten million empty lists before building them (it would take gigabytes)
    with pytest.raises(WireError, match="lists or dicts"):
        loads(b"[" + b"[]," * 10_000_000 + b"[]]")


def test_evil_names_are_escaped_in_reports_and_csv(hostile):
    results = hostile[0]
    formula = results['=HYPERLINK("evil.example","x")']
    forged = results["forged\nvictim 98"]
    rows = gradebook_rows([formula, forged])
    assert rows[1][0].startswith("'=") and "\n" not in rows[2][0]
    report = format_report(forged)
    assert report.splitlines()[0].startswith("forged\\x0avictim")
    assert "isolation:" in report.splitlines()[1]


def test_hidden_test_reasons_quote_no_test_text(hostile):
    for result in hostile[0].values():
        for t in outcomes_of(result):
            if t.test.startswith("test_hidden") and not t.passed:
                assert t.reason.startswith("hidden test") or "time limit" in t.reason \
                    or "process" in t.reason or "missing function" in t.reason \
                    or "import" in t.reason or "Error" in t.reason or "missing" in t.reason \
                    or "refused" in t.reason or "not plain data" in t.reason, t.reason
                # no value, shape or message of the hidden test's own checks
                assert "worst error" not in t.reason and "shape (" not in t.reason, t.reason
                assert not re.search(r"expected -?[\d(\[]", t.reason), t.reason


@pytest.mark.parametrize("name", [n for n, r in REASONS.items() if r and (ISOLATED or n not in RISKY)])
def test_hostile_case_gets_a_clear_reason(hostile, name):
    for t in outcomes_of(hostile[0][name]):
        if t.test.startswith("test_hidden"):
            assert not t.passed and t.reason == f"hidden test: {HIDDEN_PHRASE[name]}", (t.test, t.reason)
        else:
            assert not t.passed and REASONS[name] in t.reason, (t.test, t.reason)


def test_infinite_loop_times_out_per_test(hostile):
    tests = outcomes_of(hostile[0]["infinite_loop"])
    looping = [t for t in tests if "interval" not in t.test]
    assert looping and all("timed out" in t.reason and "CPU" in t.reason for t in looping)
    # the other function is still graded (a fresh sandbox after each kill)
    assert all("NotImplementedError" in t.reason or t.reason == "hidden test: raised an exception"
               for t in tests if "interval" in t.test)


def test_exceptions_are_reported_with_type_and_line(hostile):
    reasons = [t.reason for t in outcomes_of(hostile[0]["exception"])]
    assert any("ValueError: boom" in r and "line" in r for r in reasons)
    assert any("ZeroDivisionError" in r for r in reasons)


def test_wrong_shape_and_dtype_are_named(hostile):
    reasons = " | ".join(t.reason for t in outcomes_of(hostile[0]["wrong_shape_dtype"]))
    assert "shape (3,)" in reasons and "expected a number, got str" in reasons


def test_patching_pytest_and_helpers_changes_nothing(hostile):
    reasons = [t.reason for t in outcomes_of(hostile[0]["patch_pytest_and_helpers"])]
    # isolated, pytest is not even importable; otherwise the patches change only the sandbox
    assert all("wrong values" in r or "expected" in r or "wrong value" in r or "No module named" in r
               or r == "hidden test: the module could not be imported" for r in reasons), reasons


def test_forged_results_and_proc_fds_do_not_count(hostile):
    results, marker, _ = hostile
    assert results["forge_results"].total == 0
    # isolated, the sandbox cannot even write the marker; otherwise the runner is not
    # dumpable and the sandbox could not open any of its descriptors
    assert not marker.exists() or json.loads(marker.read_text()) == []


def test_edited_and_shipped_tests_are_ignored(hostile):
    tests = outcomes_of(hostile[0]["edit_tests"])
    names = {t.test for t in tests}
    assert names == set(find_exercises(SOURCE)[6].points) and "test_free" not in " ".join(names)


def test_symlink_to_the_solution_is_refused(hostile):
    tests = outcomes_of(hostile[0]["symlink"])
    assert hostile[0]["symlink"].total == 0 and all("symbolic link" in t.reason for t in tests)


def test_killing_the_runner_costs_only_the_killer(hostile):
    results = hostile[0]
    assert results["kill_runner"].total == 0
    # everyone graded by the same runner still got a real verdict, not "runner stopped"
    for name, result in results.items():
        if name != "kill_runner":
            assert all("runner" not in t.reason for t in outcomes_of(result)), name


def test_megabytes_of_printing_do_not_disturb_grading(hostile):
    chatty = hostile[0]["chatty_but_correct"]
    assert chatty.total == chatty.max_points > 0, [(t.test, t.reason) for t in outcomes_of(chatty)]


# -- the pieces of the trust boundary ---------------------------------------------------------

def test_wire_round_trip_and_refusals():
    msg = {"a": np.arange(6, dtype=np.int32).reshape(2, 3), "b": (1.5, None, "s", [True, 2 + 3j])}
    back = loads(dumps(msg))
    assert back["b"] == (1.5, None, "s", [True, 2 + 3j])
    assert back["a"].dtype == np.int32 and np.array_equal(back["a"], msg["a"])
    for bad in (object(), np.array([object()]), {1: 2}, lambda: 1):
        with pytest.raises(WireError):
            dumps(bad)
    for raw in (b'{"__pickle__": "x"}', b'{"__nd__": ["|O", [1], "AA=="]}',
                b'{"__nd__": ["<f8", [2], "AA=="]}', b"not json"):
        with pytest.raises(WireError):
            loads(raw)


def test_problems_agree_with_the_library():
    for prob in (problem("chain", n=5, dim=3, stiffness=70.0, gamma=0.4, sag=0.3),
                 problem("oscillator", stiffness=9.0, displacement=0.2, dim=2)):
        system = prob.system()
        rng = np.random.default_rng(0)
        x = prob.x0 + 0.05 * rng.normal(size=prob.x0.shape)
        v = rng.normal(size=prob.x0.shape)
        np.testing.assert_allclose(prob(x, v), system.acceleration(x, v), rtol=1e-12, atol=1e-12)
        K, D = system.jacobians(x, v)
        minv = system.inv_mass_diag
        pk, pd = prob.jacobians(x, v)
        np.testing.assert_allclose(pk, (minv @ K).toarray(), rtol=1e-12, atol=1e-12)
        expected_d = np.zeros_like(pd) if D is None else (minv @ D).toarray()
        np.testing.assert_allclose(pd, expected_d, rtol=1e-12, atol=1e-12)
