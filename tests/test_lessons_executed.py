"""Every lesson's code cells were executed and their outputs stored (issue 13, build item 8).

nbval already fails when a stored output is stale against the library; this test catches the
other way a notebook can mislead: a code cell that was never run (no execution count), cells run
out of order, or a notebook saved without its kernelspec, or with one that JupyterLab rewrites on
open (issue 27: the lesson then opens already modified, and autosave changes the student's clone).
"""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from ipykernel.kernelspec import get_kernel_dict

LESSONS = sorted((Path(__file__).resolve().parents[1] / "lessons").glob("[0-9][0-9]_*.ipynb"))


def test_lessons_found() -> None:
    assert len(LESSONS) >= 10, f"expected at least 10 lessons, found {len(LESSONS)}"


@pytest.mark.parametrize("path", LESSONS, ids=[p.stem for p in LESSONS])
def test_every_code_cell_executed_in_order(path: Path) -> None:
    nb = nbformat.read(path, as_version=4)
    assert nb.metadata.get("kernelspec", {}).get("name") == "python3", f"{path.name}: kernelspec"
    counts = [c.execution_count for c in nb.cells if c.cell_type == "code" and c.source.strip()]
    never = [i for i, c in enumerate(nb.cells)
             if c.cell_type == "code" and c.source.strip() and c.execution_count is None]
    assert not never, f"{path.name}: code cells {never} were never executed (run lessons/run_all.py)"
    assert counts == list(range(1, len(counts) + 1)), (
        f"{path.name}: execution counts {counts} are not 1..{len(counts)} (re-run top to bottom)")


@pytest.mark.parametrize("path", LESSONS, ids=[p.stem for p in LESSONS])
def test_kernelspec_is_the_one_ipykernel_installs(path: Path) -> None:
    """The stored kernelspec equals the spec ipykernel installs (``pip install ipykernel``, ``make venv``).

    JupyterLab writes the kernelspec of the kernel it starts into the notebook: any other display
    name marks the lesson modified the moment a student opens it.
    """
    spec = get_kernel_dict()
    stored = nbformat.read(path, as_version=4).metadata.get("kernelspec", {})
    expected = {"name": "python3", "display_name": spec["display_name"], "language": spec["language"]}
    assert dict(stored) == expected, f"{path.name}: kernelspec {dict(stored)}, ipykernel installs {expected}"


def _lessons_conftest():
    """lessons/conftest.py as a module (lessons/ is no package): its ``live_problems``."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("lessons_conftest", LESSONS[0].parent / "conftest.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("path", LESSONS, ids=[p.stem for p in LESSONS])
def test_stored_outputs_show_no_error_stderr_or_raw_repr(path: Path) -> None:
    """The stored outputs, which nbval holds every re-run to: no traceback (but where a cell is
    tagged ``raises-exception``), no stderr, no raw repr, every image a PNG of positive size.

    tests/test_lab.py checks these in the browser on each opened lesson and runs only some lessons
    live (issue: the suite under 10 minutes); nbval with lessons/conftest.py's live check carries
    them to every re-run; this holds them where no browser is installed.
    """
    live_problems = _lessons_conftest().live_problems
    nb = nbformat.read(path, as_version=4)
    found = []
    for i, cell in enumerate(nb.cells):
        if cell.cell_type != "code":
            continue
        found += [f"cell {i}: {p}" for p in live_problems(cell.outputs, cell.outputs)]
        if "raises-exception" not in cell.metadata.get("tags", []):
            found += [f"cell {i}: {o.ename}: {o.evalue}"[:200]
                      for o in cell.outputs if o.output_type == "error"]
    assert not found, f"{path.name}:\n  " + "\n  ".join(found)
