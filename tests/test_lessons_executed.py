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
