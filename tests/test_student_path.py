"""A student's path holds no answer key (issue 36, item 3; issue 39: `make lab` as root).

Both student paths are checked: `make lab` in the repository, and the course kit an instructor
hands out (`mslab release --lessons`: the lessons and their student release, no repository).

`make lab` opens JupyterLab with the lessons folder as its root and makes ``student/`` there, the
student release of ``exercises/`` (``mslab release``). Every lesson's "Try it yourself" section
links into that folder. Here the lab's own recipe (``make -n lab``) is run on a copy of the
lessons, and every link target is opened as JupyterLab resolves it (relative to the notebook, in
the lab's root): it exists, lies in the release, is the exercise's source with every solution block
replaced (no reference line that the exercise keeps only inside a solution block), and no hidden
test lies anywhere under the lab's root.
"""

from __future__ import annotations

import ast
import importlib.util
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

import nbformat
import numpy as np
import pytest

from mslab.cli import main as cli_main
from mslab.grading.expected import FILE as EXPECTED_FILE
from mslab.grading.expected import Expected
from mslab.grading.layout import BEGIN, HIDDEN
from mslab.grading.release import solution_lines, strip_solutions

ROOT = Path(__file__).resolve().parents[1]
LESSONS = sorted((ROOT / "lessons").glob("[0-9][0-9]_*.ipynb"))
LINK = re.compile(r"\]\(([^)\s]+)\)")


def _make_lab_dry_run(root: Path) -> str:
    if shutil.which("make") is None:
        pytest.skip("needs make")
    return subprocess.run(["make", "-s", "-n", "-C", str(ROOT), "lab", f"LAB_ROOT={root}", "STAMP=",
                           f"VENV={sys.prefix}"], capture_output=True, text=True, check=True).stdout


def _try_it_links(lesson: Path) -> list[str]:
    """The link targets of the lesson's "Try it yourself" section (to the end of its cell)."""
    links = []
    for cell in nbformat.read(lesson, as_version=4).cells:
        if cell.cell_type == "markdown" and "Try it yourself" in cell.source:
            links += LINK.findall(cell.source[cell.source.index("Try it yourself"):])
    return links


@pytest.fixture(scope="module", params=["make lab", "course kit"])
def lab_root(request, tmp_path_factory) -> Path:
    """JupyterLab's root as a student opens it: `make lab`'s, or the course kit's.

    `make lab`: a copy of lessons/ with the release made by its own recipe line. The course kit
    (`mslab release exercises KIT --lessons lessons`): the lessons and their student release
    without the course repository, what an instructor hands out.
    """
    if request.param == "course kit":
        kit = tmp_path_factory.mktemp("kit") / "course"
        lessons = str(ROOT / "lessons")
        assert cli_main(["release", str(ROOT / "exercises"), str(kit), "--lessons", lessons]) == 0
        assert sorted(p.name for p in kit.iterdir() if p.is_file()) == sorted(
            ["README.md"] + [p.name for p in (ROOT / "lessons").iterdir() if p.suffix in (".ipynb", ".json")])
        return kit
    root = tmp_path_factory.mktemp("lab") / "lessons"
    shutil.copytree(ROOT / "lessons", root, ignore=shutil.ignore_patterns("student", ".ipynb_checkpoints"))
    recipe = _make_lab_dry_run(root)
    release = [line for line in recipe.splitlines() if " release " in line]
    assert len(release) == 1, recipe
    subprocess.run(["bash", "-c", release[0]], cwd=ROOT, check=True, capture_output=True)
    assert f'--ServerApp.root_dir="{root}"' in recipe, recipe
    return root


def test_lab_runs_as_root_with_allow_root(tmp_path) -> None:
    """Issue 39: as uid 0 Jupyter refuses to start without --allow-root; `make lab` passes it then only."""
    flags = shlex.split(_make_lab_dry_run(tmp_path).replace("\\\n", " "))
    assert ("--allow-root" in flags) == (os.getuid() == 0)


@pytest.mark.parametrize("lesson", LESSONS, ids=[p.stem for p in LESSONS])
def test_try_it_yourself_opens_the_stripped_exercise(lesson: Path, lab_root: Path) -> None:
    links = _try_it_links(lesson)
    assert links, f"{lesson.name}: its Try it yourself section links to no exercise"
    release = (lab_root / "student").resolve()
    for href in links:
        target = (lab_root / href).resolve()      # JupyterLab: relative to the notebook's folder
        assert target.is_relative_to(release), f"{lesson.name}: {href} leads outside student/"
        assert target.is_file(), f"{lesson.name}: {href} does not exist in the release"
        original = ROOT / "exercises" / target.relative_to(release)
        source, shown = original.read_text(), target.read_text()
        assert BEGIN in source, f"{original}: expected the reference solution in the repository"
        assert shown == strip_solutions(source, str(original))
        kept = Counter(line.strip() for line in strip_solutions(source).splitlines())
        leaked = [line for line, n in Counter(solution_lines(source)).items()
                  if Counter(line.strip() for line in shown.splitlines())[line] > kept[line]]
        assert not leaked, f"{lesson.name}: {href} shows reference lines {leaked[:3]}"
        assert "raise NotImplementedError" in shown
        assert not [p for p in target.parent.iterdir() if HIDDEN.match(p.name)]


def test_lab_root_holds_no_answer_key(lab_root: Path) -> None:
    """Nothing under JupyterLab's root is a hidden test or a solution block."""
    assert sorted(p.name for p in (lab_root / "student").iterdir() if p.is_dir()) == sorted(
        p.name for p in (ROOT / "exercises").iterdir() if p.is_dir() and p.name[:2].isdigit())
    for path in lab_root.rglob("*"):
        assert not HIDDEN.match(path.name), path
        if path.suffix == ".py":
            assert BEGIN not in path.read_text(), path
    assert not (lab_root / "exercises").exists()


#: what a released public test may import from mslab: the library's public API (open: the course's
#: workbench, which a graded file cannot import) and the grading helpers that compare, build the
#: trusted acceleration and read the stored answers. Never an instructor-side key.
PUBLIC_IMPORTS = {"mslab", "mslab.derive", "mslab.effects.colliders", "mslab.effects.springs",
                  "mslab.integrators", "mslab.scenes", "mslab.stability", "mslab.state",
                  "mslab.grading.checks", "mslab.grading.expected", "mslab.grading.problems"}


def _mslab_imports(source: str) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "mslab":
            out |= {node.module} if node.module != "mslab.grading" else {f"mslab.grading.{a.name}"
                                                                          for a in node.names}
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "mslab"}
    return out


def test_released_public_tests_compute_no_answer_in_the_exercise_form(lab_root: Path) -> None:
    """Issue 36 D1: the mistakes' answers and hand-made references come as numbers from expected.json."""
    tests = sorted((lab_root / "student").glob("*/test_public.py"))
    assert len(tests) == len(list((ROOT / "exercises").glob("*/test_public.py"))), tests
    for test in tests:
        imports = _mslab_imports(test.read_text())
        assert imports <= PUBLIC_IMPORTS, f"{test.parent.name}: imports {sorted(imports - PUBLIC_IMPORTS)}"
        if "mslab.grading.expected" in imports:
            data = json.loads((test.parent / EXPECTED_FILE).read_text())  # plain JSON, numbers only
            for name in data:
                right, wrong = Expected(test).arrays(name)
                assert all(np.all(np.isfinite(a)) for a in (*right, *(w for v in wrong.values() for w in v)))
    assert importlib.util.find_spec("mslab.grading.mistakes") is None  # the old key, gone from the package


def test_the_stored_answers_are_what_the_instructor_keys_compute(capsys) -> None:
    """Each exercises/NN/expected.json reproduces from tools/exercise_keys (within round-off)."""
    path = ROOT / "tools" / "exercise_expected.py"
    spec = importlib.util.spec_from_file_location("exercise_expected", path)
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    assert tool.main(["--check"]) == 0, capsys.readouterr().out
    keyed = {p.stem[2:] for p in (ROOT / "tools" / "exercise_keys").glob("ex*.py")}
    stored = {p.parent.name[:2] for p in (ROOT / "exercises").glob("*/expected.json")}
    assert keyed == stored, (keyed, stored)
    # and the comparison is not vacuous: an answer moved by 1e-6 is reported
    data = tool.compute(ROOT / "exercises" / "01_spring_force")
    moved = json.loads(json.dumps(data))
    hint = next(iter(moved["small_net"]["mistakes"]))
    moved["small_net"]["mistakes"][hint][0][0][0] += 1e-6
    assert tool.differences(moved, json.loads(json.dumps(data))) and not tool.differences(data, data)


def test_course_kit_options_are_checked(tmp_path, capsys) -> None:
    """Bad --lessons calls end in one line, exit 2, nothing written."""
    exercises, lessons = str(ROOT / "exercises"), str(ROOT / "lessons")
    (tmp_path / "empty").mkdir()
    for args, words in ((["release", exercises, "--lessons", lessons, "--gradescope", str(tmp_path / "gs")],
                         "--lessons needs DEST"),
                        (["release", exercises, str(tmp_path / "kit"), "--lessons", str(tmp_path / "empty")],
                         "no lesson notebooks"),
                        (["release", exercises, str(ROOT / "lessons" / "kit"), "--lessons", lessons],
                         "must be outside")):
        assert cli_main(args) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("mslab: error:") and words in err[0], err
    assert not (tmp_path / "kit").exists() and not (ROOT / "lessons" / "kit").exists()
    assert not (tmp_path / "gs").exists()
