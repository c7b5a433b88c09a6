"""The student release: solutions replaced by ``raise NotImplementedError``, hidden tests left out."""

from __future__ import annotations

import ast
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mslab.files import current_umask
from mslab.grading.layout import BEGIN, END, EXERCISE_NAME, HIDDEN

#: never copied into a release
SKIP_DIRS = {"__pycache__", ".pytest_cache", ".ipynb_checkpoints", ".ruff_cache"}
SKIP_SUFFIXES = {".pyc", ".pyo"}
#: anything that looks like a solution marker (variants the release does not understand)
MARKER_LIKE = re.compile(r"(BEGIN|END)[ _]+(SOLUTION|HIDDEN)", re.IGNORECASE)

STUDENT_README = """# Exercises

One folder per exercise, in the order of the lessons. Each holds a `README.md` (the task and
its equations), one Python file with the functions to write (replace every
`raise NotImplementedError`; keep the file name and the function names) and
`test_public.py`, tests you can run yourself (with `expected.json`, the numbers some of them
compare with: keep it beside them).

The lessons are notebooks. In the course kit (this folder is then its `student/`) they are in
the folder above: after `python -m pip install "mslab[students]"` (below), run
`python -m jupyter lab` there, and each lesson's "Try it yourself" opens your file here. In each
lesson, Kernel > Restart Kernel and Run All Cells brings its sliders to life.

## Run the public tests on your work

The public tests need `mslab` (the package your course hands out; the tests compare your
results with the library) and `pytest`, both in the same Python. Install them once:

```
python -m pip install "mslab[students]"
```

Then, from this folder, in a terminal or in JupyterLab's (File > New > Terminal):

```
python -m pytest 03_heun_midpoint          # one exercise
python -m pytest .                         # all of them
```

Use the same `python` for both (`python3` or `py` where `python` is another one). A bare
`pytest` may belong to another Python, which then stops with "No module named 'mslab'".

## How you are graded

Your grade comes from these public tests and from hidden tests on other inputs (some drawn
at random when you are graded), with the points shown by `@pytest.mark.points(n)`. Only the
one file with your functions is graded, as a plain file; while it is graded your code cannot
import `mslab` (write the methods yourself, with numpy), has no network, and each test has a
time limit (10 s by default) and a memory limit. Printing is allowed but ignored.

## Submit

Hand in this folder as it is (`<your name>/NN_topic/<file>.py`), as plain files: no links.
"""


COURSE_README = """# The course

The lessons are the notebooks in this folder (start with `00_mass_spring_systems.ipynb`);
`student/` holds the exercises: each one's task, the file you complete and tests you can run
(`student/README.md`). Install mslab, JupyterLab and pytest into one Python once:

```
python -m pip install "mslab[students]"
```

then, in this folder, `python -m jupyter lab`. In a lesson, Kernel > Restart Kernel and Run All
Cells brings its sliders to life, and its "Try it yourself" opens your file in `student/`.
Hand in what `student/README.md` says.
"""
#: what a course kit takes from the lessons folder: the notebooks and the data files they read
LESSON_FILES = ("*.ipynb", "*.json")


def strip_solutions(text: str, filename: str = "<source>") -> str:
    """Replace every ``# BEGIN SOLUTION`` ... ``# END SOLUTION`` block by one ``raise``.

    The ``raise NotImplementedError`` keeps the indentation of the BEGIN line. Unbalanced
    markers raise ValueError naming the line; so does a result that does not parse.
    """
    out: list[str] = []
    inside = None
    for number, line in enumerate(text.splitlines(keepends=True), start=1):
        marker = line.strip()
        if marker.startswith(BEGIN):
            if inside is not None:
                raise ValueError(f"{filename}:{number}: '{BEGIN}' inside a solution block "
                                 f"(opened line {inside})")
            inside = number
            indent = line[: len(line) - len(line.lstrip())]
            out.append(f"{indent}raise NotImplementedError\n")
        elif marker.startswith(END):
            if inside is None:
                raise ValueError(f"{filename}:{number}: '{END}' without '{BEGIN}'")
            inside = None
        elif inside is None:
            out.append(line)
    if inside is not None:
        raise ValueError(f"{filename}:{inside}: '{BEGIN}' is never closed")
    result = "".join(out)
    try:
        ast.parse(result, filename=filename)
    except SyntaxError as err:
        raise ValueError(f"{filename}: the student version does not parse: {err}") from None
    return result


def solution_lines(text: str) -> list[str]:
    """Return the stripped, non-empty lines inside solution blocks (what a release must not contain)."""
    lines, inside = [], False
    for line in text.splitlines():
        marker = line.strip()
        if marker.startswith(BEGIN):
            inside = True
        elif marker.startswith(END):
            inside = False
        elif inside and marker:
            lines.append(marker)
    return lines


def _released_files(src: Path):
    """(relative path, source path) of everything that goes into the release."""
    for dirpath, dirnames, filenames in os.walk(src):
        dirnames[:] = sorted(d for d in dirnames if d not in SKIP_DIRS and not d.startswith("."))
        rel_dir = Path(dirpath).relative_to(src)
        for name in sorted(filenames):
            path = Path(dirpath) / name
            skip = name.startswith(".") or path.suffix in SKIP_SUFFIXES or HIDDEN.match(name)
            if skip or path.is_symlink():
                continue
            yield rel_dir / name, path


def marker_warnings(rel: Path, text: str) -> list[str]:
    """Lines that look like solution markers but that the release does not understand.

    In a ``.py`` file a marker must be exactly ``# BEGIN SOLUTION`` / ``# END SOLUTION``
    (after indentation); anything else (``### BEGIN SOLUTION``, ``#BEGIN SOLUTION``,
    ``# BEGIN HIDDEN TESTS``) would be released as it is, with the solution under it. In any
    other file every marker is copied as it is.
    """
    out = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not MARKER_LIKE.search(line):
            continue
        marker = line.strip()
        if rel.suffix != ".py":
            out.append(f"{rel}:{number}: solution marker in a file that is not .py (copied as it is)")
        elif not (marker.startswith(BEGIN) or marker.startswith(END)):
            out.append(f"{rel}:{number}: marker not understood (released as it is): {marker[:60]!r}")
    return out


def release(src: str | Path, dest: str | Path, force: bool = False,
            warnings: list[str] | None = None) -> list[Path]:
    """Write the student version of ``src`` into ``dest``; returns the files written.

    The top ``README.md`` of the release is the student README (how to run the public tests
    on their folder and submit), not the instructor's. Lines that look like solution markers
    the release does not understand are appended to ``warnings``. The release is built in a
    temporary sibling folder and renamed into place, so a failure (say, unbalanced markers)
    leaves no half release behind; its permissions follow the umask.
    """
    warnings = [] if warnings is None else warnings
    src, dest = Path(src).resolve(), Path(dest).resolve()
    if not src.is_dir():
        raise ValueError(f"{src}: no such folder")
    if dest == src or dest.is_relative_to(src) or src.is_relative_to(dest):
        raise ValueError(f"{dest}: the release must be outside the source folder {src}")
    if not any(EXERCISE_NAME.match(p.name) for p in src.iterdir() if p.is_dir()):
        raise ValueError(f"{src}: no exercise folders (NN_topic) found")
    written = []
    with _built_in_place(dest, force) as tmp:
        for rel, path in _released_files(src):
            target = tmp / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            if rel == Path("README.md"):
                target.write_text(STUDENT_README)
            elif path.suffix == ".py":
                text = path.read_text()
                warnings.extend(marker_warnings(rel, text))
                target.write_text(strip_solutions(text, str(rel)) if BEGIN in text else text)
            else:
                data = path.read_bytes()
                warnings.extend(marker_warnings(rel, data.decode("utf-8", errors="replace")))
                target.write_bytes(data)
            written.append(dest / rel)
        if not (tmp / "README.md").exists():
            (tmp / "README.md").write_text(STUDENT_README)
            written.append(dest / "README.md")
    return written


@contextmanager
def _built_in_place(dest: Path, force: bool) -> Iterator[Path]:
    """Yield a temporary sibling of ``dest`` to build in; it replaces ``dest`` when the block ends.

    Refused if ``dest`` exists and is not empty without ``force``; a failure leaves nothing
    behind. The result's permissions follow the umask.
    """
    if dest.exists() and any(dest.iterdir()) and not force:
        raise ValueError(f"{dest}: exists and is not empty (use --force to replace it)")
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}-", dir=dest.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~current_umask())
        if dest.exists():
            shutil.rmtree(dest)
        os.replace(tmp, dest)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def release_course(src: str | Path, lessons: str | Path, dest: str | Path, force: bool = False,
                   warnings: list[str] | None = None) -> list[Path]:
    """Write a course kit: the lessons in ``dest`` and the student release of ``src`` in ``dest/student``.

    The layout of ``make lab`` (JupyterLab's root is the lessons folder, whose "Try it
    yourself" links lead into ``student/``) without the instructor's tree, so a student needs
    nothing of the course repository. From ``lessons`` only the notebooks and the data files
    they read (:data:`LESSON_FILES`, top level) are copied; a ``README.md`` tells how to start.
    Built in a temporary sibling folder and renamed into place, like :func:`release`.
    """
    src, lessons, dest = Path(src).resolve(), Path(lessons).resolve(), Path(dest).resolve()
    notebooks = sorted(p for pattern in LESSON_FILES for p in lessons.glob(pattern) if p.is_file())
    if not any(p.suffix == ".ipynb" for p in notebooks):
        raise ValueError(f"{lessons}: no lesson notebooks (*.ipynb) found")
    for inside in (lessons, src):
        if dest == inside or dest.is_relative_to(inside) or inside.is_relative_to(dest):
            raise ValueError(f"{dest}: the kit must be outside {inside}")
    with _built_in_place(dest, force) as tmp:
        written = [tmp / p.name for p in notebooks]
        for path in notebooks:
            shutil.copyfile(path, tmp / path.name)
        (tmp / "README.md").write_text(COURSE_README)
        written += [tmp / "README.md", *release(src, tmp / "student", warnings=warnings)]
    return [dest / p.relative_to(tmp) for p in written]
