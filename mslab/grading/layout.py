"""Where things are: exercise folders, the student's file, the tests and their points."""

from __future__ import annotations

import ast
import os
import re
import stat
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

BEGIN, END = "# BEGIN SOLUTION", "# END SOLUTION"
#: an exercise folder is named ``NN_topic``
EXERCISE_NAME = re.compile(r"^\d\d_[A-Za-z0-9_]+$")
HIDDEN = re.compile(r"^test_hidden.*\.py$")
TEST = re.compile(r"^test_.*\.py$")
#: largest student file the grader reads (bytes)
MAX_SOURCE = 1_000_000


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
        Test file name -> source text (public and hidden), read once.
    points : dict
        ``"file::test_name"`` -> points, from the ``@pytest.mark.points(n)`` markers.
    """

    name: str
    folder: Path
    module: str
    tests: dict[str, str] = field(default_factory=dict)
    points: dict[str, float] = field(default_factory=dict)

    @property
    def max_points(self) -> float:
        """Points the exercise's tests are worth."""
        return float(sum(self.points.values()))


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
        found.append(ex)
    if not found:
        raise ValueError(f"{source}: no exercise folders (NN_topic) found")
    return found


def is_submission(folder: Path, exercises: list[Exercise]) -> bool:
    """Tell whether a submission folder holds at least one exercise folder (or one exercise's file)."""
    names = {e.name for e in exercises}
    return any((folder / n).is_dir() for n in names)


def expand_submissions(paths: Iterable[str | Path], exercises: list[Exercise]) -> list[tuple[Path, str]]:
    """Return the submission folders of the command line: each path is one submission or a class of them.

    Returns ``(folder, refusal)`` pairs: ``refusal`` is empty, or why the folder is not
    graded (a symbolic link: the student's work must be the student's own files).
    """
    out = []
    for raw in paths:
        path = Path(raw)
        if not path.is_dir():
            raise ValueError(f"{path}: no such folder")
        if is_submission(path, exercises):
            out.append((path, _refusal(path)))
            continue
        students = [p for p in sorted(path.iterdir()) if p.is_dir() and not p.name.startswith(".")]
        if not students:
            raise ValueError(f"{path}: neither a submission (no exercise folders) nor a class of submissions")
        out.extend((p, _refusal(p)) for p in students)
    return out


def _refusal(folder: Path) -> str:
    return "the submission folder is a symbolic link (refused)" if folder.is_symlink() else ""


def read_student_file(submission: Path, exercise: Exercise) -> tuple[str | None, str]:
    """Return the student's source for an exercise and ``""``, or None and why it was not read.

    Only plain files count: no symbolic link (the folder, the exercise folder or the file),
    no file with a second hard link (it could be the reference solution), nothing but a
    regular file, opened without following links.
    """
    folder = submission / exercise.name
    path = folder / exercise.module
    name = exercise.module
    try:
        if folder.is_symlink():
            return None, f"{exercise.name} is a symbolic link (refused)"
        if path.is_symlink():
            return None, f"{name} is a symbolic link (refused)"
        if not os.path.lexists(path):
            return None, f"{name} is missing from the submission"
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(fd, "rb") as fh:
            st = os.fstat(fh.fileno())
            if not stat.S_ISREG(st.st_mode):
                return None, f"{name} is not a regular file (refused)"
            if st.st_nlink != 1:
                return None, f"{name} has {st.st_nlink} hard links (refused: submit a plain copy)"
            if st.st_size > MAX_SOURCE:
                return None, f"{name} is larger than {MAX_SOURCE} bytes"
            data = fh.read(MAX_SOURCE + 1)
        return data[:MAX_SOURCE].decode("utf-8", errors="replace"), ""
    except OSError as err:
        return None, f"{name} could not be read ({err.strerror})"
