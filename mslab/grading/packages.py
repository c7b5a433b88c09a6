"""Platform packages: a Gradescope autograder and a PrairieLearn external grader from one release.

``mslab release --gradescope DIR`` writes the autograder Gradescope builds its image from
(https://gradescope-autograders.readthedocs.io/en/latest/specs/): ``setup.sh`` (run once,
as root: a Python >= 3.11 venv in ``/opt/mslab-venv`` with the bundled mslab), and
``run_autograder`` (run per submission, as root, in ``/autograder``: grades
``/autograder/submission/`` and writes ``/autograder/results/results.json``), next to the
instructor's tests and ``mslab-src/``; ``DIR.zip`` holds the same files at its root, ready
to upload.

``mslab release --prairielearn DIR`` writes an external grader
(https://prairielearn.readthedocs.io/en/latest/externalGrading/): a ``Dockerfile`` for the
grading image (Python and the bundled mslab, no tests: an image may be public) and
``serverFilesCourse/mslab_grader/`` for the course repository (the tests and ``run.sh``, the
entry point: ``run.sh NN_topic`` grades ``/grade/student/`` into
``/grade/results/results.json``); ``info.json`` gives each question's
``externalGradingOptions``.

Both run the grader with ``--isolation rlimits`` unless ``MSLAB_ISOLATION`` says otherwise:
a platform's container normally refuses the user namespaces that bubblewrap and the
namespace jail need, and grades as root (rlimits mode as root runs the student as a
throwaway user who cannot read the tests). The entry makes the tests root's only (mode
700) before grading. No reference solution is packaged: the exercise's file is the
student version, its solution blocks empty. ``MSLAB_AUTOGRADER_ROOT`` / ``MSLAB_GRADE_ROOT``
stand for ``/autograder`` / ``/grade`` and ``MSLAB_PYTHON`` for the interpreter (the tests
run the entry scripts here in those layouts).
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import shutil
import tempfile
import tomllib
from collections.abc import Callable
from pathlib import Path

from mslab.files import current_umask
from mslab.grading.layout import BEGIN, END, find_exercises
from mslab.grading.release import SKIP_DIRS, SKIP_SUFFIXES, strip_solutions

PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: the extra whose requirements the grader needs beyond mslab's own (pytest runs the tests)
GRADING_EXTRA = "grading"
PL_GRADER = "mslab_grader"
EMPTY_SOLUTION = f"\n{BEGIN}\n# (the reference solution is not part of a platform package)\n{END}\n"

GRADESCOPE_SETUP = """#!/usr/bin/env bash
# Gradescope runs this once, as root, when it builds the autograder's image (Ubuntu).
set -euo pipefail
PY="$(command -v python3.13 || command -v python3.12 || command -v python3.11 || true)"
if [ -z "$PY" ]; then
    apt-get install -y python3.11 python3.11-venv
    PY=python3.11
fi
"$PY" -m venv /opt/mslab-venv
/opt/mslab-venv/bin/python -m pip install --upgrade pip
/opt/mslab-venv/bin/python -m pip install /autograder/source/mslab-src
"""

GRADESCOPE_RUN = """#!/usr/bin/env bash
# Gradescope runs this for every submission, as root, in /autograder: it grades
# /autograder/submission/ and writes /autograder/results/results.json.
ROOT="${{MSLAB_AUTOGRADER_ROOT:-/autograder}}"
PY="${{MSLAB_PYTHON:-/opt/mslab-venv/bin/python}}"
cd "$ROOT" || exit 1
exec "$PY" -m mslab.commands.platform_entry gradescope "$ROOT/submission" "$ROOT/source/exercises" \\
    "$ROOT/results/results.json" --isolation "${{MSLAB_ISOLATION:-rlimits}}" {exercises}
"""

PRAIRIELEARN_RUN = """#!/usr/bin/env bash
# PrairieLearn's entry point: run.sh NN_topic grades /grade/student/ into /grade/results/results.json.
ROOT="${MSLAB_GRADE_ROOT:-/grade}"
PY="${MSLAB_PYTHON:-python3}"
HERE="$(cd "$(dirname "$0")" && pwd)"
exec "$PY" -m mslab.commands.platform_entry prairielearn "$ROOT/student" "$HERE/exercises" \\
    "$ROOT/results/results.json" --isolation "${MSLAB_ISOLATION:-rlimits}" "$@"
"""

DOCKERFILE = """# The grading image of the PrairieLearn questions: Python and mslab, no tests (they come from
# serverFilesCourse at grading time). Build and push it, then name it in each question's info.json:
#   docker build -t YOURNAME/mslab-grader . && docker push YOURNAME/mslab-grader
FROM python:3.12-slim
COPY mslab-src /opt/mslab-src
RUN python -m pip install --no-cache-dir /opt/mslab-src && rm -rf /opt/mslab-src
"""

PYPROJECT = """[build-system]
requires = ["setuptools>=68"]
build-backend = "setuptools.build_meta"

[project]
name = "mslab"
version = {version}
requires-python = ">=3.11"
dependencies = {dependencies}

[project.scripts]
mslab = "mslab.cli:main"

[tool.setuptools.packages.find]
include = ["mslab*"]

[tool.setuptools.package-data]
"*" = ["*.toml", "*.json", "*.txt"]
"""


def grader_requirements() -> list[str]:
    """Return what the grader needs installed: mslab's requirements and those of its ``grading`` extra.

    Read from the checkout's ``pyproject.toml`` when mslab runs from one (an editable
    install's metadata may predate it), else from the installed metadata.
    """
    pyproject = PACKAGE_DIR.parent / "pyproject.toml"
    if pyproject.is_file():
        project = tomllib.loads(pyproject.read_text()).get("project", {})
        if project.get("name") == "mslab":
            extra = project.get("optional-dependencies", {}).get(GRADING_EXTRA, [])
            return [*project.get("dependencies", []), *extra]
    out = []
    for req in importlib.metadata.requires("mslab") or []:
        spec, _, marker = req.partition(";")
        marker = marker.replace(" ", "").replace("'", '"')
        if not marker or marker == f'extra=="{GRADING_EXTRA}"':
            out.append(spec.strip())
    return out


def _bundle_mslab(dest: Path) -> None:
    """Write ``dest/`` as an installable copy of the running mslab (its code and a pyproject.toml)."""
    shutil.copytree(PACKAGE_DIR, dest / "mslab", ignore=shutil.ignore_patterns(
        *SKIP_DIRS, *(f"*{s}" for s in SKIP_SUFFIXES)))
    version = importlib.metadata.version("mslab")
    (dest / "pyproject.toml").write_text(PYPROJECT.format(version=json.dumps(version),
                                                          dependencies=json.dumps(grader_requirements())))


def _package_exercises(src: Path, dest: Path, only: list[str] | None) -> list[str]:
    """Copy the tests of the chosen exercises and each exercise's file without its solution."""
    exercises = find_exercises(src)
    if only:
        unknown = sorted(set(only) - {e.name for e in exercises})
        if unknown:
            raise ValueError(f"unknown exercise(s): {', '.join(unknown)}")
        exercises = [e for e in exercises if e.name in only]
    for ex in exercises:
        folder = dest / ex.name
        folder.mkdir(parents=True)
        for name, text in sorted(ex.tests.items()):  # the tests and their stored answers, as read
            (folder / name).write_text(text)
        text = (ex.folder / ex.module).read_text()
        (folder / ex.module).write_text(strip_solutions(text, ex.module) + EMPTY_SOLUTION)
    return [e.name for e in exercises]


def _write_script(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    path.chmod(0o755)


def _build(dest: str | Path, force: bool, fill: Callable[[Path], None]) -> list[Path]:
    """Build a package with ``fill(tmp)`` in a temporary sibling, then rename it to ``dest``."""
    dest = Path(dest).resolve()
    if dest.exists() and (not dest.is_dir() or any(dest.iterdir())) and not force:
        raise ValueError(f"{dest}: exists and is not empty (use --force to replace it)")
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}-", dir=dest.parent))
    try:
        fill(tmp)
        os.chmod(tmp, 0o777 & ~current_umask())
        if dest.exists():
            shutil.rmtree(dest) if dest.is_dir() else dest.unlink()
        os.replace(tmp, dest)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return sorted(p for p in dest.rglob("*") if p.is_file())


def build_gradescope(src: str | Path, dest: str | Path, only: list[str] | None = None,
                     force: bool = False) -> list[Path]:
    """Write Gradescope's autograder for the exercises ``only`` (default all) of ``src`` to ``dest``.

    Also writes ``dest.zip`` (the files at its root, as Gradescope wants them). Returns the
    files of ``dest``.
    """
    def fill(tmp: Path) -> None:
        names = _package_exercises(Path(src), tmp / "exercises", only)
        _bundle_mslab(tmp / "mslab-src")
        _write_script(tmp / "setup.sh", GRADESCOPE_SETUP)
        flags = " ".join(f"--exercise {name}" for name in names)
        _write_script(tmp / "run_autograder", GRADESCOPE_RUN.format(exercises=flags))

    files = _build(dest, force, fill)
    dest = Path(dest).resolve()
    archive = shutil.make_archive(str(dest.with_name(f".{dest.name}-zip")), "zip", root_dir=dest)
    os.replace(archive, dest.with_name(f"{dest.name}.zip"))
    return files


def build_prairielearn(src: str | Path, dest: str | Path, only: list[str] | None = None,
                       force: bool = False) -> list[Path]:
    """Write PrairieLearn's external grader for the exercises ``only`` (default all) of ``src``."""
    def fill(tmp: Path) -> None:
        grader = tmp / "serverFilesCourse" / PL_GRADER
        names = _package_exercises(Path(src), grader / "exercises", only)
        _write_script(grader / "run.sh", PRAIRIELEARN_RUN)
        _bundle_mslab(tmp / "mslab-src")
        (tmp / "Dockerfile").write_text(DOCKERFILE)
        options = {name: {"externalGradingOptions": {
            "enabled": True, "image": "YOURNAME/mslab-grader", "serverFilesCourse": [f"{PL_GRADER}/"],
            "entrypoint": f"/grade/serverFilesCourse/{PL_GRADER}/run.sh {name}", "timeout": 300}}
            for name in names}
        (tmp / "info.json").write_text(json.dumps(options, indent=2) + "\n")

    return _build(dest, force, fill)
