"""Grades where courses keep them: the Gradescope, PrairieLearn and Canvas files, and the platform packages.

The JSON schemas below are written from each platform's published field list (cited in
mslab/grading/platforms.py): every field we write must be one the platform defines, with
the type and range it defines. The packages' entry scripts are run here in the platform's
folder layout (a path prefix stands for /autograder and /grade), as root where the suite
runs as root, with the namespace modes forced off (``--isolation rlimits``).
"""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import stat
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import jsonschema
import pytest
from test_grading_trust import _open_views

from mslab.cli import main as cli_main
from mslab.grading.autograde import ExerciseResult, SubmissionResult
from mslab.grading.autograde import TestResult as Outcome
from mslab.grading.isolation import DESCRIPTION
from mslab.grading.platforms import (
    CANVAS_COLUMNS,
    gradescope_results,
    prairielearn_results,
    read_canvas,
    write_grades,
)

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
#: packaged and graded on the platforms (its public tests read stored answers: expected.json travels too)
TARGET, MODULE = "03_heun_midpoint", "heun_midpoint.py"

_VISIBILITY = {"enum": ["hidden", "after_due_date", "after_published", "visible"]}
#: Gradescope's autograder specification, "Output format" (docs/specs.md of gradescope/autograder_samples)
GRADESCOPE_SCHEMA = {
    "type": "object",
    "properties": {
        "score": {"type": "number"},
        "execution_time": {"type": "number"},
        "output": {"type": "string"},
        "visibility": _VISIBILITY,
        "stdout_visibility": _VISIBILITY,
        "extra_data": {"type": "object"},
        "tests": {"type": "array", "items": {
            "type": "object",
            "properties": {
                "score": {"type": "number"},
                "max_score": {"type": "number"},
                "status": {"enum": ["passed", "failed"]},
                "name": {"type": "string"},
                "number": {"type": "string"},
                "output": {"type": "string"},
                "tags": {"type": "array", "items": {"type": "string"}},
                "visibility": _VISIBILITY,
                "extra_data": {"type": "object"},
            },
            "additionalProperties": False,
        }},
        "leaderboard": {"type": "array"},
    },
    "additionalProperties": False,
    # "score: optional, but required if not on each test case"
    "anyOf": [{"required": ["score"]},
              {"required": ["tests"], "properties": {"tests": {"items": {"required": ["score"]}}}}],
}
#: PrairieLearn's "External Grading", "Grading results" (docs/externalGrading.md of PrairieLearn)
PRAIRIELEARN_SCHEMA = {
    "type": "object",
    "properties": {
        "gradable": {"type": "boolean"},
        "score": {"type": "number", "minimum": 0.0, "maximum": 1.0},
        "format_errors": {"anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}}]},
        "message": {"type": "string"},
        "output": {"type": "string"},
        "images": {"type": "array"},
        "tests": {"type": "array", "items": {
            "type": "object",
            "properties": {
                "name": {"type": "string"},
                "description": {"type": "string"},
                "points": {"type": "number"},
                "max_points": {"type": "number"},
                "message": {"type": "string"},
                "output": {"type": "string"},
                "images": {"type": "array"},
            },
            "required": ["name", "points", "max_points"],
            "additionalProperties": False,
        }},
    },
    # "If the submission is gradable, the result only has one mandatory field: score"
    "if": {"properties": {"gradable": {"const": False}}, "required": ["gradable"]},
    "else": {"required": ["score"]},
}
SECRET = "seed_31337"
MISSING = "euler_steps.py is missing from the submission"


def _result(student: str = "alice", hidden_reason: str = "hidden test: wrong value") -> SubmissionResult:
    """A graded submission of two exercises: public and hidden tests, passed and failed."""
    ex1 = ExerciseResult("01_spring_force", [
        Outcome("test_public.py::test_hooke", 2.0, 2.0, True, "ok"),
        Outcome("test_public.py::test_jacobian", 0.0, 3.0, False, "jacobian: wrong value at [0, 1]"),
        Outcome(f"test_hidden.py::test_{SECRET}", 0.0, 4.0, False, hidden_reason),
        Outcome("test_hidden.py::test_more", 1.5, 1.5, True, "ok")])
    ex2 = ExerciseResult("02_euler_steps", [
        Outcome("test_public.py::test_step", 0.0, 2.0, False, MISSING),
        Outcome(f"test_hidden.py::test_{SECRET}_2", 0.0, 2.0, False, MISSING)], errors=[MISSING])
    return SubmissionResult(f"/class/{student}", student, [ex1, ex2], isolation="test", resources="none")


def test_gradescope_results_follow_the_published_format_and_round_trip(tmp_path):
    res = _result()
    doc = gradescope_results(res)
    jsonschema.validate(doc, GRADESCOPE_SCHEMA)
    path = write_grades(tmp_path / "results.json", "gradescope", [res])
    back = json.loads(path.read_text())
    assert back == doc
    assert back["score"] == res.total == sum(t["score"] for t in back["tests"]) == 3.5
    assert sum(t["max_score"] for t in back["tests"]) == res.max_points == 14.5
    public = [t for t in back["tests"] if "public" in t["tags"]]
    hidden = [t for t in back["tests"] if "hidden" in t["tags"]]
    assert [t["visibility"] for t in public] == ["visible"] * 3
    assert [t["visibility"] for t in hidden] == ["after_published"] * 3
    assert [t["status"] == "passed" for t in back["tests"]] == [True, False, False, True, False, False]
    assert public[1]["output"] == "jacobian: wrong value at [0, 1]"


def test_prairielearn_results_follow_the_published_format_and_round_trip(tmp_path):
    res = _result()
    doc = prairielearn_results(res)
    jsonschema.validate(doc, PRAIRIELEARN_SCHEMA)
    path = write_grades(tmp_path / "results.json", "prairielearn", [res])
    back = json.loads(path.read_text())
    assert back == doc and back["gradable"] is True
    assert back["score"] == pytest.approx(3.5 / 14.5, rel=1e-15)
    assert [t["points"] for t in back["tests"]] == [2.0, 0.0, 0.0, 1.5, 0.0, 0.0]
    assert [t["max_points"] for t in back["tests"]] == [2.0, 3.0, 4.0, 1.5, 2.0, 2.0]
    assert len(path.read_bytes()) < 1_000_000


def test_prairielearn_marks_a_submission_with_nothing_to_grade_not_gradable():
    res = _result()
    res.exercises = res.exercises[1:]  # only the exercise whose file is missing
    doc = prairielearn_results(res)
    jsonschema.validate(doc, PRAIRIELEARN_SCHEMA)
    assert doc["gradable"] is False
    assert doc["format_errors"] == ["02_euler_steps: euler_steps.py is missing from the submission"]


def test_canvas_gradebook_has_canvas_columns_and_round_trips(tmp_path):
    results = [_result("alice"), _result("=HYPERLINK(evil)")]
    results[1].exercises[0].tests[0] = Outcome("test_public.py::test_hooke", 0.0, 2.0, False, "x")
    path = write_grades(tmp_path / "canvas.csv", "canvas", results)
    rows = list(csv.reader(path.open(newline="")))
    assert tuple(rows[0][:5]) == CANVAS_COLUMNS and rows[0][5] == "mslab exercises"
    assert rows[1][0] == "Points Possible" and rows[1][5] == "14.5"
    # the folder name is the SIS Login ID, never an escaped one (no one's login): empty for a formula
    assert [r[3] for r in rows[2:]] == ["alice", ""]
    title, possible, scores = read_canvas(path)
    assert (title, possible) == ("mslab exercises", 14.5)
    assert scores == {"alice": 3.5, "'=HYPERLINK(evil)": 1.5}  # a formula is not a formula
    path = write_grades(tmp_path / "canvas.csv", "canvas", results[:1], assignment="Exercise 2 (81234)")
    assert read_canvas(path)[0] == "Exercise 2 (81234)"


@pytest.mark.parametrize("fmt", ["gradescope", "prairielearn", "canvas"])
def test_no_hidden_test_name_nor_message_reaches_a_platform(tmp_path, fmt):
    # the grader's reason of a hidden test is a fixed phrase; even if it were not, it stays out
    results = [_result(hidden_reason=f"expected 0.25 for {SECRET}")]
    text = write_grades(tmp_path / "out", fmt, results).read_text()
    assert SECRET not in text and "0.25" not in text
    if fmt != "canvas":
        doc = json.loads(text)
        names = [t["name"] for t in doc["tests"]]
        assert names[2] == "01_spring_force: hidden test 1" and names[5] == "02_euler_steps: hidden test 1"


def test_one_submission_per_results_json_and_options_checked(tmp_path, capsys):
    with pytest.raises(ValueError, match="one submission"):
        write_grades(tmp_path / "r.json", "gradescope", [_result("a"), _result("b")])
    assert not (tmp_path / "r.json").exists()
    sub, src = str(tmp_path), ["--source", str(SOURCE)]
    for args, message in (([sub, "--format", "gradescope"], "--format: gradescope needs --output FILE"),
                          ([sub, sub, "--format", "prairielearn", "--output", "r.json"],
                           "--format: prairielearn writes the results.json of one submission, not of 2"),
                          ([sub, "--format", "canvas", "--output", "c.csv", "--assignment", "a\nb"],
                           "--assignment: a one-line title"),
                          ([sub, "--assignment", "A (1)", "--output", "c.csv"],
                           "--assignment: only for --format canvas")):
        assert cli_main(["grade", *args, *src]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"mslab: error: {message}") and len(err.splitlines()) == 1, err


@pytest.fixture(scope="module")
def small_class(tmp_path_factory) -> Path:
    """Exercise 02 of a class of two: the reference solution, and an empty release file."""
    base = tmp_path_factory.mktemp("platform_class") / "class"
    for name in ("good", "empty"):
        (base / name / TARGET).mkdir(parents=True)
    shutil.copyfile(SOURCE / TARGET / MODULE, base / "good" / TARGET / MODULE)
    (base / "empty" / TARGET / MODULE).write_text("def forward_euler_step(x, v, prob, dt):\n"
                                                  "    raise NotImplementedError\n")
    return base


def test_grade_writes_each_platform_format(small_class, tmp_path, capsys):
    common = ["--source", str(SOURCE), "--exercise", TARGET]
    assert cli_main(["grade", str(small_class), *common, "--format", "canvas", "--output",
                     str(tmp_path / "canvas.csv"), "--assignment", "Euler (4711)"]) == 0
    title, possible, scores = read_canvas(tmp_path / "canvas.csv")
    assert (title, possible, scores) == ("Euler (4711)", 13.0, {"empty": 0.0, "good": 13.0})
    for fmt, schema in (("gradescope", GRADESCOPE_SCHEMA), ("prairielearn", PRAIRIELEARN_SCHEMA)):
        out = tmp_path / f"{fmt}.json"
        args = ["grade", str(small_class / "good"), *common, "--format", fmt, "--output", str(out)]
        assert cli_main(args) == 0
        doc = json.loads(out.read_text())
        jsonschema.validate(doc, schema)
        assert doc["score"] == (13.0 if fmt == "gradescope" else 1.0)
        hidden_source = (SOURCE / TARGET / "test_hidden.py").read_text()
        names = re.findall(r"^def (test_\w+)", hidden_source, flags=re.M)
        assert names and not any(n in out.read_text() for n in names)
    capsys.readouterr()


# --- the platform packages, run in the platform's folder layout ----------------------------------

HOSTILE = '''
import sys

STOLEN = {targets!r}
SPILL = {spill!r}


def _steal():
    found = []
    for path in STOLEN:
        try:
            with open(path) as fh:
                found.append("LEAK " + fh.read()[:400])
        except Exception as err:
            found.append("blocked " + type(err).__name__)
    text = " | ".join(found)
    print(text)
    print(text, file=sys.stderr)
    for out in SPILL:
        try:
            with open(out, "w") as fh:
                fh.write(text)
        except Exception:
            pass
    return text


def heun_step(x, v, prob, dt):
    raise RuntimeError(_steal())


midpoint_step = heun_step
'''


def _hidden_text() -> list[str]:
    """Pieces of the hidden tests that must never reach a student: each test's name and its lines."""
    text = (SOURCE / TARGET / "test_hidden.py").read_text()
    names = re.findall(r"^def (test_\w+)", text, flags=re.M)
    lines = [line.strip() for line in text.splitlines() if len(line.strip()) > 30]
    assert len(names) >= 3 and len(lines) >= 10
    return names + lines


def _run(command: list[str], env: dict) -> subprocess.CompletedProcess:
    """Run a package's entry script as the platform would (the suite's user: root where it runs as root).

    As root, the interpreter must be reachable by the throwaway user the student runs as;
    a pyenv under /root is not, so the script runs in a private mount namespace where the
    folders on the way are opened (test_grading_trust._open_views; the system is not changed).
    """
    env = {k: v for k, v in os.environ.items() if not k.startswith("MSLAB_")} | env
    env["MSLAB_PYTHON"] = sys.executable
    argv = ["bash", *command]
    if os.geteuid() == 0:
        if not shutil.which("unshare"):
            pytest.skip("grading as root needs unshare here (to open the interpreter's folders)")
        keep = Path(command[0]).parent.parent / ".views"
        keep.mkdir(exist_ok=True)
        views = _open_views(keep, [sys.base_prefix, sys.prefix, str(ROOT)])
        argv = ["unshare", "--mount", "--propagation", "private", "sh", "-c",
                views + "exec " + " ".join(f"'{a}'" for a in argv)]
    return subprocess.run(argv, env=env, cwd=Path(command[0]).parent, capture_output=True, text=True,
                          timeout=600)


def _everything_written(run: subprocess.CompletedProcess, results: Path) -> str:
    files = [p.read_text(errors="replace") for p in sorted(results.rglob("*")) if p.is_file()]
    return "\n".join([run.stdout, run.stderr, *files])


@pytest.fixture(scope="module")
def packages(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("packages")
    assert cli_main(["release", str(SOURCE), "--gradescope", str(base / "gradescope"),
                     "--prairielearn", str(base / "prairielearn"), "--exercise", TARGET]) == 0
    return base


def test_packages_hold_tests_but_no_solution(packages):
    from mslab.grading.release import solution_lines

    with zipfile.ZipFile(packages / "gradescope.zip") as z:
        names = set(z.namelist())
        assert {"setup.sh", "run_autograder", f"exercises/{TARGET}/test_hidden.py",
                f"exercises/{TARGET}/expected.json"} <= names
        assert all((z.getinfo(n).external_attr >> 16) & 0o111 for n in ("setup.sh", "run_autograder"))
    assert not any(n.startswith(("exercises/01_", "exercises/02_")) for n in names)
    solution = solution_lines((SOURCE / TARGET / MODULE).read_text())
    for folder in (packages / "gradescope" / "exercises",
                   packages / "prairielearn" / "serverFilesCourse" / "mslab_grader" / "exercises"):
        text = "\n".join(p.read_text() for p in folder.rglob("*.py"))
        assert not [line for line in solution if line in text]
    options = json.loads((packages / "prairielearn" / "info.json").read_text())[TARGET]
    entry = options["externalGradingOptions"]["entrypoint"]
    assert entry == f"/grade/serverFilesCourse/mslab_grader/run.sh {TARGET}"
    pyproject = tomllib.loads((packages / "gradescope" / "mslab-src" / "pyproject.toml").read_text())
    assert any(r.startswith("pytest") for r in pyproject["project"]["dependencies"])  # the runner is pytest


def test_release_package_options_are_checked(tmp_path, capsys):
    for args, message in (([str(tmp_path / "out"), "--exercise", TARGET],
                           "--exercise: --exercise applies to --gradescope / --prairielearn only"),
                          (["--gradescope", str(tmp_path / "gs"), "--exercise", "99_nothing"],
                           "unknown exercise(s): 99_nothing")):
        assert cli_main(["release", str(SOURCE), *args]) == 2
        err = capsys.readouterr().err
        assert err == f"mslab: error: {message}\n", err
    assert not (tmp_path / "gs").exists() and not (tmp_path / "gs.zip").exists()


def _layout(platform: str, packages: Path, base: Path, source: str,
            folder: bool = False) -> tuple[Path, list[str], dict]:
    """The platform's folder layout under ``base`` with ``source`` uploaded: (root, command, env).

    The upload is flat (the one file), or with ``folder`` inside its exercise folder (a zip).

    Gradescope: /autograder/source/ from the zip, /autograder/run_autograder, submission/.
    PrairieLearn: /grade/serverFilesCourse/mslab_grader/ (the question's entry point), student/.
    """
    if platform == "gradescope":
        root = base / "autograder"
        with zipfile.ZipFile(packages / "gradescope.zip") as z:
            z.extractall(root / "source")
        shutil.copy2(root / "source" / "run_autograder", root / "run_autograder")
        (root / "run_autograder").chmod(0o755)
        upload, command, env = root / "submission", [str(root / "run_autograder")], "MSLAB_AUTOGRADER_ROOT"
    else:
        root = base / "grade"
        shutil.copytree(packages / "prairielearn" / "serverFilesCourse", root / "serverFilesCourse")
        entry = root / "serverFilesCourse" / "mslab_grader" / "run.sh"
        upload, command, env = root / "student", [str(entry), TARGET], "MSLAB_GRADE_ROOT"
    upload = upload / TARGET if folder else upload
    upload.mkdir(parents=True)
    (upload / MODULE).write_text(source)
    return root, command, {env: str(root)}


def _tests_folder(platform: str, root: Path) -> Path:
    inside = ["source"] if platform == "gradescope" else ["serverFilesCourse", "mslab_grader"]
    return root.joinpath(*inside, "exercises", TARGET)


@pytest.mark.parametrize("platform, folder", [("gradescope", False), ("gradescope", True),
                                              ("prairielearn", False)])
def test_a_platform_package_grades_an_honest_upload_in_rlimits_mode(packages, tmp_path, platform, folder):
    root, command, env = _layout(platform, packages, tmp_path, (SOURCE / TARGET / MODULE).read_text(), folder)
    run = _run(command, env)
    assert run.returncode == 0, run.stderr
    doc = json.loads((root / "results" / "results.json").read_text())
    if platform == "gradescope":
        jsonschema.validate(doc, GRADESCOPE_SCHEMA)
        assert doc["score"] == 13.0 == sum(t["max_score"] for t in doc["tests"]), doc["output"]
        assert doc["extra_data"]["isolation"] == DESCRIPTION["rlimits"]  # namespaces forced off
    else:
        jsonschema.validate(doc, PRAIRIELEARN_SCHEMA)
        assert doc["gradable"] is True and doc["score"] == 1.0, doc["output"]
    assert stat.S_IMODE(_tests_folder(platform, root).stat().st_mode) == 0o700
    text = _everything_written(run, root / "results")
    assert not [piece for piece in _hidden_text() if piece in text]


@pytest.mark.parametrize("platform", ["gradescope", "prairielearn"])
def test_a_hostile_upload_reads_no_hidden_test(packages, tmp_path, platform):
    """Issue 40: as root in rlimits mode the student ran as root and quoted test_hidden.py in a
    public test's reason; the rlimits privilege drop (a throwaway uid) must leave it unreadable.
    (With MSLAB_ISOLATION=auto, namespaces, the same attack reads "blocked FileNotFoundError".)"""
    root = tmp_path / ("autograder" if platform == "gradescope" else "grade")
    tests, results = _tests_folder(platform, root), root / "results"
    attack = HOSTILE.format(targets=[str(tests / "test_hidden.py"), str(tests / "test_public.py")],
                            spill=[str(results / "results.json"), str(results / "leak.txt")])
    root, command, env = _layout(platform, packages, tmp_path, attack)
    run = _run(command, env)
    assert run.returncode == 0, run.stderr
    doc = json.loads((results / "results.json").read_text())
    jsonschema.validate(doc, GRADESCOPE_SCHEMA if platform == "gradescope" else PRAIRIELEARN_SCHEMA)
    assert doc["score"] == 0.0
    text = _everything_written(run, results)
    assert "blocked" in text  # the attack ran, and what it could say reached the results
    assert "LEAK" not in text and not [piece for piece in _hidden_text() if piece in text]


# --- the student release's README: the commands a student types ----------------------------------

def test_release_readme_commands_use_the_python_that_has_mslab(tmp_path):
    """Issue 39: a bare ``pytest`` may be another Python's; the README's commands never call it."""
    release = tmp_path / "release"
    assert cli_main(["release", str(SOURCE), str(release)]) == 0
    readme = (release / "README.md").read_text()
    blocks = re.findall(r"^```\n(.*?)^```", readme, flags=re.M | re.S)
    commands = [line.split("#")[0].strip() for block in blocks for line in block.splitlines() if line.strip()]
    installs = [c for c in commands if " pip " in f" {c} "]
    runs = [c for c in commands if c not in installs]
    assert installs == ['python -m pip install "mslab[students]"'] and len(runs) == 2, commands
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert any(r.startswith("pytest") for r in extras["students"]) and "mslab[lessons]" in extras["students"]
    # another Python's pytest first on PATH: a student's `pytest` would be this one
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "pytest").write_text("#!/bin/sh\necho \"ModuleNotFoundError: No module named 'mslab'\"\n"
                                    "exit 4\n")
    (bin_dir / "pytest").chmod(0o755)
    (bin_dir / "python").write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')  # the student's Python
    (bin_dir / "python").chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", PYTEST_ADDOPTS="-p no:randomly",
               PYTEST_DISABLE_PLUGIN_AUTOLOAD="1")
    publics = sum(t.startswith("test_public") for t in _points_of_all())
    for command, expected in zip(runs, (None, publics), strict=True):
        proc = subprocess.run(command, shell=True, cwd=release, env=env, capture_output=True, text=True,
                              timeout=600)
        assert "No module named" not in proc.stdout + proc.stderr, proc.stdout[-2000:]
        assert proc.returncode == 1 and re.search(r"\d+ failed in", proc.stdout), proc.stdout[-2000:]
        if expected is not None:  # every public test ran (and failed: nothing is implemented)
            assert f"{expected} failed in" in proc.stdout, proc.stdout[-500:]


def _points_of_all() -> list[str]:
    from mslab.grading import find_exercises

    return [test for ex in find_exercises(SOURCE) for test in ex.points]
