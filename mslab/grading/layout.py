"""Where things are: exercise folders, the student's file, the tests and their points."""

from __future__ import annotations

import ast
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from mslab.grading.expected import FILE as EXPECTED_FILE
from mslab.grading.intake import (
    LAYOUTS,
    Submission,
    class_entry,
    is_grader_file,
    notebook_code,
    read_path,
    unique_names,
)
from mslab.grading.report import printable

BEGIN, END = "# BEGIN SOLUTION", "# END SOLUTION"
#: an exercise folder is named ``NN_topic``
EXERCISE_NAME = re.compile(r"^\d\d_[A-Za-z0-9_]+$")
HIDDEN = re.compile(r"^test_hidden.*\.py$")
TEST = re.compile(r"^test_.*\.py$")


@dataclass
class Exercise:
    """One exercise of the instructor's source tree.

    Attributes
    ----------
    name : str
        Folder name, e.g. ``01_spring_force``.
    module : str
        File name of the student's source (the one with solution blocks).
    tests : dict
        Test file name -> source text (public and hidden), read once; with the public tests'
        stored answers (``expected.json``), which travel with them to the runner.
    points : dict
        ``"file::test_name"`` -> points, from the ``@pytest.mark.points(n)`` markers.
    """

    name: str
    folder: Path
    module: str
    tests: dict[str, str] = field(default_factory=dict)
    points: dict[str, float] = field(default_factory=dict)

    @property
    def hands_problems(self) -> bool:
        """Whether a test may hand the student a problem (then its sandbox gets ``problems.py``).

        Read from the tests' imports (:func:`imports_problems`): a test module that imports
        neither :mod:`mslab.grading.problems` nor a check that builds a problem gets a sandbox
        without the file, whose spring forces would be exercise 01's answer. A word in a comment
        or a string is no import.
        """
        return any(imports_problems(text) for name, text in self.tests.items() if name.endswith(".py"))

    @property
    def max_points(self) -> float:
        """Points the exercise's tests are worth."""
        return float(sum(self.points.values()))


#: the checks of :mod:`mslab.grading.checks` that build a problem and hand it to student code
HANDING_CHECKS = frozenset({"step_order", "observed_order", "swinging_spring", "*"})


def imports_problems(source: str) -> bool:
    """Whether a test module imports :mod:`mslab.grading.problems` or a check of :data:`HANDING_CHECKS`.

    From its syntax tree (``import ...`` and ``from ... import ...`` anywhere in it), so a
    comment or a string that names a problem counts for nothing; a whole-module import of
    ``mslab.grading.checks`` counts (any check may then be called), and so does a module that
    does not parse (the conservative answer).
    """
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return True
    for node in ast.walk(tree):
        if isinstance(node, ast.Import) and any(
                a.name.startswith(("mslab.grading.problems", "mslab.grading.checks")) for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and node.module:
            names = {a.name for a in node.names}
            if node.module.startswith("mslab.grading.problems") or (
                    node.module == "mslab.grading" and names & {"problems", "checks", "*"}) or (
                    node.module == "mslab.grading.checks" and names & HANDING_CHECKS):
                return True
    return False


def default_source() -> Path | None:
    """``exercises/`` when the current folder is the instructor's tree (it has hidden tests), else None.

    The grader never falls back to the checkout's own ``exercises/`` from another folder:
    a course grading its own copy must say ``--source``.
    """
    here = Path("exercises")
    if here.is_dir() and any(here.glob("*/test_hidden*.py")):
        return here
    return None


def test_points(filename: str, source: str) -> dict[str, float]:
    """Points of every ``test_*`` function of a test file (1 if it has no marker)."""
    tree = ast.parse(source, filename=filename)
    out = {}
    for node in tree.body:
        if not isinstance(node, ast.FunctionDef) or not node.name.startswith("test"):
            continue
        points = 1.0
        for dec in node.decorator_list:
            if (isinstance(dec, ast.Call) and isinstance(dec.func, ast.Attribute)
                    and dec.func.attr == "points" and dec.args and isinstance(dec.args[0], ast.Constant)):
                points = float(dec.args[0].value)
        out[f"{filename}::{node.name}"] = points
    return out


def find_exercises(source: str | Path) -> list[Exercise]:
    """Return the exercise folders of an instructor's tree, in order (ValueError if there are none)."""
    source = Path(source)
    if not source.is_dir():
        raise ValueError(f"{source}: not a folder of exercises")
    found = []
    for folder in sorted(p for p in source.iterdir() if p.is_dir() and EXERCISE_NAME.match(p.name)):
        modules = [p for p in sorted(folder.glob("*.py"))
                   if not TEST.match(p.name) and p.name != "conftest.py" and BEGIN in p.read_text()]
        if len(modules) != 1:
            raise ValueError(f"{folder}: expected exactly one file with '{BEGIN}' blocks, "
                             f"found {len(modules)}")
        ex = Exercise(folder.name, folder, modules[0].name)
        for test in sorted(folder.glob("test_*.py"), key=lambda p: (bool(HIDDEN.match(p.name)), p.name)):
            text = test.read_text()
            ex.tests[test.name] = text
            ex.points.update(test_points(test.name, text))
        data = folder / EXPECTED_FILE  # the public tests' stored answers travel with them
        if data.is_file():
            ex.tests[data.name] = data.read_text()
        found.append(ex)
    if not found:
        raise ValueError(f"{source}: no exercise folders (NN_topic) found")
    return found


def _candidates(exercise: Exercise, flat: bool) -> list[list[str]]:
    """Where a submission keeps an exercise's file: its folder, else (flat) the top; .py before .ipynb."""
    stem = exercise.module.rsplit(".", 1)[0]
    out = [[exercise.name, exercise.module], [exercise.name, stem + ".ipynb"]]
    return out + ([[exercise.module], [stem + ".ipynb"]] if flat else [])


def looks_like_submission(folder: Path, exercises: list[Exercise], flat: bool = True) -> bool:
    """Tell whether a folder holds an exercise's file where a submission keeps it (never by names alone).

    ``flat=False`` counts files in exercise folders only (``NN_topic/FILE``).
    """
    return any(os.path.lexists(folder.joinpath(*parts))
               for ex in exercises for parts in _candidates(ex, flat))


def _student_like(entry: Path, exercises: list[Exercise]) -> bool:
    """Tell whether an entry would be a student's in a class.

    That is a folder holding an exercise's file, a zip, or (one exercise graded) a ``.py`` /
    ``.ipynb`` other than the exercise's, ``conftest.py`` or a test.
    """
    if entry.name.startswith(".") or entry.is_symlink() or entry.name in {e.name for e in exercises}:
        return False
    if entry.is_dir():
        return looks_like_submission(entry, exercises)
    if entry.name.endswith(".zip"):
        return True
    own = {p[-1] for ex in exercises for p in _candidates(ex, True)} | {"conftest.py"}
    loose = len(exercises) == 1 and entry.name.endswith((".py", ".ipynb"))  # as :func:`class_entry` grades
    return loose and entry.name not in own and not TEST.match(entry.name)


def _is_one_submission(path: Path, exercises: list[Exercise], layout: str, skip: set[str]) -> bool:
    """Apply the auto rule: one submission if its file is there and no other entry looks like a student."""
    if layout != "auto":
        return layout == "submission"
    entries = [p for p in sorted(path.iterdir()) if os.path.abspath(p) not in skip and not is_grader_file(p)]
    students = [p.name for p in entries if _student_like(p, exercises)]
    if looks_like_submission(path, exercises):
        if students:
            raise ValueError(f"{path}: holds an exercise's file and other entries that look like students' "
                             f"({printable(students[0], 40)}, {len(students)} in all): say --layout class "
                             "or --layout submission")
        return True
    names = {e.name for e in exercises}  # exercise folders, none with its file: an empty submission
    return not students and any(p.is_dir() and p.name in names for p in entries)


def expand_submissions(paths: Iterable[str | Path], exercises: list[Exercise], layout: str = "auto",
                       ignore: Iterable[str | Path] = ()) -> list[Submission]:
    """Return the submissions of the command line: each path is one submission or a class of them.

    ``layout`` is the rule of :mod:`mslab.grading.intake` (``auto``, ``class``,
    ``submission``). Every entry of a class is a :class:`Submission`, refused ones with
    their reason; ``ignore`` lists files the grading itself writes (the gradebook, its journal).
    """
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r} (choose from {', '.join(LAYOUTS)})")
    skip = {os.path.abspath(p) for p in ignore}
    out = []
    for raw in paths:
        path = Path(raw)
        if not path.is_dir():
            raise ValueError(f"{path}: no such folder")
        if _is_one_submission(path, exercises, layout, skip):
            refusal = "the submission folder is a symbolic link (refused)" if path.is_symlink() else ""
            out.append(Submission(path, path.name or str(path), refusal=refusal))
            continue
        entries = [p for p in sorted(path.iterdir())
                   if os.path.abspath(p) not in skip and not is_grader_file(p)]
        if not entries:
            raise ValueError(f"{path}: an empty class folder (no student folder, .zip or file)")
        out.extend(class_entry(p, len(exercises) == 1) for p in entries)
    return unique_names(out)


def read_student_file(submission: Submission, exercise: Exercise) -> tuple[str | None, str]:
    """Return the student's source for an exercise and ``""``, or None and why it was not read.

    Read once, without following any symbolic link (:func:`mslab.grading.intake.read_path`);
    a zip's files are those its sandbox unpacked (``submission.files``, set by the grader with
    :func:`mslab.grading.unpack.unpack_zip`); a notebook counts by its code cells. A flat
    submission (the file at the top, as the platforms hand it over) counts when the
    exercise's folder is absent.
    """
    if submission.refusal:
        return None, submission.refusal
    if submission.kind == "file":
        data, why = read_path(submission.path.parent, [submission.path.name])
        return _decode(data, why, submission.path.name, exercise)
    if submission.kind == "zip":
        files = submission.files
        if files is None:
            return None, f"{submission.path.name}: not unpacked (mslab.grading.unpack.unpack_zip)"
        for parts in _candidates(exercise, exercise.name not in {n.split("/")[0] for n in files}):
            if "/".join(parts) in files:
                return _decode(files["/".join(parts)], "", parts[-1], exercise)
        return None, f"{exercise.module} is missing from the submission"
    flat = not os.path.lexists(submission.path / exercise.name)
    for parts in _candidates(exercise, flat):
        data, why = read_path(submission.path, parts)
        if why != "missing":
            return _decode(data, why, parts[-1], exercise)
    return None, f"{exercise.module} is missing from the submission"


def _decode(data: bytes | None, why: str, label: str, exercise: Exercise) -> tuple[str | None, str]:
    if data is None:
        return None, why
    if label.endswith(".ipynb"):
        return notebook_code(data, label)
    if not label.endswith(".py"):
        return None, f"{label}: not a Python file or notebook (refused)"
    return data.decode("utf-8", errors="replace"), ""
