"""tools/lessons_check.py: which markdown sentences need a claim, and a false claim fails nbval."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("lessons_check", ROOT / "tools" / "lessons_check.py")
lessons_check = importlib.util.module_from_spec(_spec)
sys.modules["lessons_check"] = lessons_check
_spec.loader.exec_module(lessons_check)

CLAIM_CELL = ('from mslab.claims import claim\n'
              'ratio = {ratio}\n'
              'claim("halving h quarters the error", 3.5 < ratio < 4.5, id="quarter",\n'
              '      ratio=f"{{ratio:.1f}}")')
HOLDS = "claim holds: [quarter] halving h quarters the error  (ratio = 3.9)\n"


def notebook(markdown: list[str], ratio: str = "3.9", output: str = HOLDS) -> nbformat.NotebookNode:
    """Markdown cells, then one claim cell with ``output`` stored as if it had run."""
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.cells = [nbformat.v4.new_markdown_cell(m) for m in markdown]
    code = nbformat.v4.new_code_cell(CLAIM_CELL.format(ratio=ratio), execution_count=1)
    code.outputs = [nbformat.v4.new_output("stream", name="stdout", text=output)] if output else []
    nb.cells.append(code)
    return nb


def findings(tmp_path: Path, markdown: list[str], **kw: str) -> list[str]:
    path = tmp_path / "00_x.ipynb"
    nbformat.write(notebook(markdown, **kw), path)
    return [f.text for f in lessons_check.check_notebook(path)]


@pytest.mark.parametrize("sentence", [
    "The error falls fourfold when h is halved.",
    "Leapfrog's energy stays bounded.",
    "RK4 is 14.9 times as accurate.",
    "The run took 5200 steps.",
    "Symplectic Euler is faster than RK4.",
])
def test_numbers_and_verdicts_are_listed(tmp_path, sentence):
    assert findings(tmp_path, [f"Intro without anything. {sentence} Another plain sentence."]) == [sentence]


@pytest.mark.parametrize("sentence", [
    "Newton's law (lecture notes, eq. 3) and the spring force (eqs. 1–2) from the lecture.",
    "As lesson 04 and section 2.3 showed, see §2.8 and exercise 02.",
    "We step with `rk4` and rk4 in 2D and 3D.",
    "The amplification factor is $R(z) = 1 + z + z^2/2$, and $$|R(2i)| = 1.$$",
    "## 3. A heading with 12 numbers",
    "A [link](https://example.org/42) to nowhere.",
])
def test_equations_citations_and_names_are_not_numbers(tmp_path, sentence):
    assert findings(tmp_path, [sentence]) == []


def test_claim_and_no_claim_comments_back_sentences(tmp_path):
    md = ("Halving h quarters the error. <!-- claim: quarter --> "
          "The spring has k = 100 N/m. <!-- no-claim: a parameter of the scene --> "
          "Nobody backs this 42.\n\n"
          "<!-- no-claim: a list of definitions -->\n1. a first-order system, 2 of them.\n\n"
          "* <!-- no-claim: a definition --> order 2 means ...")
    assert findings(tmp_path, [md]) == ["Nobody backs this 42."]


def test_list_items_are_sentences_of_their_own(tmp_path):
    md = "We have\n\n* a plain item\n* 12 items here\n* another plain item"
    assert findings(tmp_path, [md]) == ["* 12 items here"]


def test_claim_ids_must_exist_and_hold(tmp_path):
    assert findings(tmp_path, ["It is 4. <!-- claim: nothere -->"]) == [
        "claim 'nothere' is named but no code cell defines it"]
    assert findings(tmp_path, ["It is 4. <!-- claim: quarter -->"], output="") == [
        "claim 'quarter' has no stored 'claim holds' output"]


def test_command_line_exit_codes(tmp_path, capsys):
    good, bad = tmp_path / "00_good.ipynb", tmp_path / "01_bad.ipynb"
    nbformat.write(notebook(["Halving h quarters the error. <!-- claim: quarter -->"]), good)
    nbformat.write(notebook(["It drifts by 3 %."]), bad)
    assert lessons_check.main([str(good)]) == 0
    assert lessons_check.main([str(good), str(bad)]) == 1
    out = capsys.readouterr().out
    assert out == f"{bad}:cell 0: It drifts by 3 %.\n"
    (tmp_path / "broken.ipynb").write_text("{not json")
    assert lessons_check.main([str(tmp_path / "broken.ipynb")]) == 2


def _nbval(path: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:randomly",
                           "-p", "no:cacheprovider", "--nbval", "--nbval-current-env", str(path)],
                          cwd=path.parent, env=env, capture_output=True, text=True, timeout=300)


def test_a_claim_made_false_fails_nbval(tmp_path):
    """The stored output is what the true claim printed; perturbing its value makes the cell raise."""
    path = tmp_path / "00_claim.ipynb"
    nbformat.write(notebook(["Halving h quarters the error. <!-- claim: quarter -->"]), path)
    assert _nbval(path).returncode == 0
    nbformat.write(notebook(["Halving h quarters the error. <!-- claim: quarter -->"], ratio="2.0"), path)
    result = _nbval(path)
    assert result.returncode != 0
    assert "ClaimError" in result.stdout and "claim false: [quarter]" in result.stdout
