"""tools/lessons_check.py: which markdown sentences need a claim, and a false claim fails nbval."""

from __future__ import annotations

import importlib.util
import os
import re
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
    "Only the implicit method survives.",
    "It needs several steps.",
    "The factor is $|R| = 0.5$ there.",
])
def test_numbers_and_verdicts_are_listed(tmp_path, sentence):
    assert findings(tmp_path, [f"Intro without anything. {sentence} Another plain sentence."]) == [sentence]


@pytest.mark.parametrize("sentence", [
    "Newton's law (lecture notes, eq. 3) and the spring force (eqs. 1–2) from the lecture.",
    "As lesson 04 and section 2.3 showed, see §2.8 and exercise 02.",
    "We step with `rk4` and rk4 in 2D and 3D.",
    "The amplification factor is $R(z) = 1 + z + z^2/2$, and $$e^{z} = O(h^2).$$",
    "## 3. A heading with 12 numbers",
    "A [link](https://example.org/42) to nowhere.",
])
def test_equations_citations_and_names_are_not_numbers(tmp_path, sentence):
    assert findings(tmp_path, [sentence]) == []


def test_claim_and_no_claim_comments_back_sentences(tmp_path):
    md = ("Halving h quarters the error. <!-- claim: quarter --> "
          "The spring has k = 100 N/m. <!-- no-claim: parameter: of the scene --> "
          "Nobody backs this 42.\n\n"
          "<!-- no-claim: definition -->\n1. a first-order system, 2 of them.\n\n"
          "* <!-- no-claim: definition --> order 2 means ...")
    assert findings(tmp_path, [md]) == ["Nobody backs this 42."]


def test_no_claim_takes_a_reason_of_the_vocabulary_and_names_no_claim(tmp_path):
    bad = findings(tmp_path, ["It is 4. <!-- no-claim: a fact of mathematics -->"])
    assert len(bad) == 1 and "reason 'a' is not one of definition" in bad[0]
    bad = findings(tmp_path, ["In short: 4. <!-- no-claim: outline: summary of quarter -->"])
    assert len(bad) == 1 and "names claims ['quarter']" in bad[0]


def test_list_items_are_sentences_of_their_own(tmp_path):
    md = "We have\n\n* a plain item\n* 12 items here\n* another plain item"
    assert findings(tmp_path, [md]) == ["* 12 items here"]


def test_claim_ids_must_exist_and_hold(tmp_path):
    assert findings(tmp_path, ["It is 3.9. <!-- claim: nothere -->"]) == [
        "claim 'nothere' is named but no code cell defines it"]
    assert findings(tmp_path, ["It is 3.9. <!-- claim: quarter -->"], output="") == [
        "claim 'quarter' has no stored 'claim holds' output"]


VALUES = ("claim holds: [v] rk4 is faster and the energy stays bounded  "
          "(ratio = 14.53, steps = 5200, drift = 2.2e-08, share = 0.70, 0.51, saved = 31 %, k_times = 178)\n")


@pytest.mark.parametrize("sentence", [
    "RK4 is 14.5 times as accurate.",                 # printed 14.53, to the sentence's digits
    "RK4 is 15 times as accurate.",
    "It took 5200 steps.",
    "The error stays below $10^{-7}$ J.",             # a bound, inside an equation
    "The error stays below 1e-7 J.",
    "The error is $2.2 \\times 10^{-8}$ J.",
    "It is more than 5000 steps.",
    "Lumping saves about 30 % of the error.",
    "The share is 0.5-0.7 of the error.",
    "The share is between 0.4 and 0.6 of the error.",
    "The drag halves the error.",                     # 0.51
    "The stiffness is hundreds of times k.",          # 178
    "It is more than twice as accurate.",             # 14.53 (a bound on the magnitude word)
    "It is more than seven times as accurate.",       # a number word that is a factor
    "The spread is a factor of ten or more.",         # "or more": a bound after the number
    "RK4 is faster here.",
    "The energy stays bounded.",
])
def test_sentences_that_their_claim_carries(tmp_path, sentence):
    assert findings(tmp_path, [f"{sentence} <!-- claim: v -->"], output=VALUES) == []


@pytest.mark.parametrize("sentence, problem", [
    ("RK4 is 14.6 times as accurate.", "14.6: no printed value fits"),
    ("It took 5300 steps.", "5300: no printed value fits"),
    ("The error stays below $10^{-9}$ J.", "below 1e-9: no printed value fits"),
    ("It is more than 70000 steps.", "above 70000: no printed value fits"),
    ("Lumping saves about 40 % of the error.", "about 40: no printed value fits"),
    ("The share is 0.8-0.9 of the error.", "0.8-0.9: no printed value fits"),
    ("$|R(iy)| = 0.68$ there.", "0.68: no printed value fits"),
    ("The stiffness is tens of times k.", "'tens': no printed value in"),
    ("It is twice as accurate.", "'twice': no printed value in"),
    ("It is several times as accurate.", "'several': no printed value in"),
    ("It is less than half as accurate.", "'half' (a share below 0.5"),          # 0.70 is not below
    ("It is seven times as accurate.", "7: no printed value fits"),
    ("RK4 is slower here.", "'slower' is in no claim's statement"),
    ("Only RK4 is accurate.", "'Only' is in no claim's statement"),
])
def test_sentences_that_their_claim_contradicts(tmp_path, sentence, problem):
    few = "claim holds: [v] rk4 is faster  (k_times = 178, share = 0.70)\n"
    output = few if re.search("times|twice|half", sentence) and "$" not in sentence else VALUES
    found = findings(tmp_path, [f"{sentence} <!-- claim: v -->"], output=output)
    assert len(found) == 1 and problem in found[0], found


SHARES = ("claim holds: [v] rk4 loses energy  "
          "(ratio = 0.21, lost = 62 %, peaks = 0.0028, 0.0063, runs = 19, k_times = 178, count = 31)\n")


@pytest.mark.parametrize("sentence", [
    "Its peak is about a fifth of leapfrog's.",            # 0.21
    "It loses most of its energy early.",                  # 62 %: "most of" is a share, not a verdict
    "The majority of the energy is lost.",
    "It loses three fifths of its energy.",                # 0.555-0.636
    "It loses more than half of its energy.",              # 62 % > 50 %
    "It loses over a third of its energy.",
    "It keeps less than half of its energy.",              # 0.21
    "The peak is less than half the limit.",               # a bound on the share, not the word "half"
    "It loses half of it or more.",                        # 62 %
    "It loses more\nthan half of its energy.",             # a bound across a line break
])
def test_share_words_that_a_printed_share_carries(tmp_path, sentence):
    assert findings(tmp_path, [f"{sentence} <!-- claim: v -->"], output=SHARES) == []


@pytest.mark.parametrize("sentence, problem, printed", [
    ("Its peak is about a quarter of leapfrog's.", "'a quarter' (a share in 0.227-0.278", "0.21, 62 %"),
    ("It loses two thirds of its energy.", "'two thirds' (a share in 0.63-0.697", "0.21, 62 %"),
    ("Nine in ten runs survive.", "'Nine in ten' (a share in 0.889-0.909", "0.85, 19"),
    ("It loses a third of its energy.", "'a third' (a share in 0.303-0.37", "31"),    # a percent needs its %
    ("A minority of the energy is lost.", "'A minority' (a share in 0-0.5", "62 %, 178"),
    ("It loses more than two thirds of its energy.", "'two thirds' (a share above 0.667", "62 %, 178"),
    ("It keeps less than a fifth of its energy.", "'a fifth' (a share below 0.2", "62 %, 0.21"),
    ("The peak is more than half the limit.", "'half' (a share above 0.5", "0.21, 178"),  # 178 is no share
    ("The peak is less than half the limit.", "'half' (a share below 0.5", "0.52"),   # not below 0.556
    ("It loses a third of it or more.", "'a third' (a share above 0.333", "0.21, 3"),
    ("It loses at most a tenth of it.", "'a tenth' (a share below 0.1", "0.21, 3"),
])
def test_share_words_that_no_printed_share_carries(tmp_path, sentence, problem, printed):
    output = f"claim holds: [v] the runs survive  (values = {printed})\n"
    found = findings(tmp_path, [f"{sentence} <!-- claim: v -->"], output=output)
    assert len(found) == 1 and problem in found[0] and "no printed value fits" in found[0], found


@pytest.mark.parametrize("sentence", [
    "About a fifth of the energy is lost.",
    "Most of the runs survive.",
    "Nine in ten runs survive.",
])
def test_a_share_word_needs_backing(tmp_path, sentence):
    assert findings(tmp_path, [f"Intro. {sentence} Another plain sentence."]) == [sentence]


@pytest.mark.parametrize("sentence", [
    "It converges over one and a quarter periods.",        # a mixed number, not a share
    "It reaches a centimetre within half a minute.",       # an amount, not a share
    "We take a third-order method.",
])
def test_amounts_are_not_share_words(tmp_path, sentence):
    assert findings(tmp_path, [f"Intro. {sentence} Another plain sentence."]) == []


def test_bounds_read_across_line_breaks_and_no_more_than_is_an_upper_bound(tmp_path):
    steps = "claim holds: [v] it is slow  (steps = 5200)\n"
    assert findings(tmp_path, ["It took no more than 6000 steps. <!-- claim: v -->"], output=steps) == []
    assert findings(tmp_path, ["It took more\nthan 5000 steps. <!-- claim: v -->"], output=steps) == []
    assert findings(tmp_path, ["It took no more than 5000 steps. <!-- claim: v -->"], output=steps) == [
        "It took no more than 5000 steps. <!-- claim: v --> [below 5000: no printed value fits]"]


def test_at_most_and_at_least_are_bounds_not_superlatives(tmp_path):
    assert findings(tmp_path, ["It took at most 6000 and at least 5000 steps. <!-- claim: v -->"],
                    output="claim holds: [v] it is slow  (steps = 5200)\n") == []


def test_a_lead_comment_backs_and_checks_every_sentence_of_its_block(tmp_path):
    md = "<!-- claim: v --> RK4 is 14.5 times as accurate. It took 5300 steps."
    assert findings(tmp_path, [md], output=VALUES) == [
        "It took 5300 steps. [5300: no printed value fits]"]


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


def test_a_folded_solution_is_not_checked(tmp_path):
    md = ("Derive it. <!-- no-claim: question -->\n\n"
          "<details><summary>Solution</summary>\n\nIt is 42.\n</details>")
    assert findings(tmp_path, [md]) == []
    assert findings(tmp_path, ["It is 42.\n\n" + md]) == ["It is 42."]


MUTATIONS = [   # (lesson, text of a backed sentence, the same text made wrong, what the checker must say)
    ("00_mass_spring_systems.ipynb", "drag has removed more than 2.5 J", "drag has removed more than 25 J",
     "above 25: no printed value fits"),
    ("04_implicit_euler.ipynb", "vibrate at hundreds of radians per second",
     "vibrate at thousands of radians per second", "'thousands': no printed value in"),
    ("02_heun_midpoint_rk4.ipynb", "per unit of work the higher order wins",
     "per unit of work the lower order wins", "'lower' is in no claim's statement"),
    ("03_verlet_leapfrog.ipynb", "a quarter of RK4's work", "a third of RK4's work",      # a share word
     "'a third' (a share in 0.303-0.37"),
    ("03_verlet_leapfrog.ipynb", "make up more than half of the net loss",                # a bound on a share
     "make up less than half of the net loss", "'half' (a share below 0.5"),
    # an outside reviewer's edits (2026-11-29) that any printed value used to let through: a bound with a
    # unit is held to the printed values of that unit (5 s, not the 1 cm threshold), a count noun to the
    # values of that name (steps = 6, 6), a factor to the printed ratios (5.4, 21.4, not a median of 0.56)
    ("03_verlet_leapfrog.ipynb", "apart within 10 s", "apart within 2 s", "below 2: no printed value fits"),
    ("04_implicit_euler.ipynb", "blow up within 6 steps", "blow up within 3 steps",
     "below 3: no printed value fits"),
    ("06_energy_drift.ipynb", "more than three times the 30 s value", "less than three times the 30 s value",
     "below 3: no printed value fits"),
    # and the same reviewer's swapped subjects: the claim's statement says which side each one is on
    ("05_dahlquist_stability.ipynb", "Radau IIA (order 3) damps more than SDIRK2\n(order 2)",
     "SDIRK2 (order 2) damps more than Radau IIA\n(order 3)", "the sentence puts sdirk2 before radau_iia2"),
    ("00_mass_spring_systems.ipynb", "but lumping the mass where the material is does better",
     "but equal masses do better", "'better': the sentence says it of equal, its claim of lumped"),
    ("02_heun_midpoint_rk4.ipynb", "Heun's about 2000 times RK4's", "RK4's about 2000 times Heun's",
     "'times': the sentence puts rk4 before heun"),
]


@pytest.mark.parametrize("sentence, statement, problem", [
    ("Leapfrog is faster than RK4.", "rk4 is faster than leapfrog", "puts leapfrog before rk4"),
    ("Symplectic Euler's error is 5 times Heun's.", "heun's error is 5 times symplectic_euler's",
     "puts symplectic_euler before heun"),
    ("Forward Euler does better.", "heun does better than euler", "says it of euler, its claim of heun"),
    ("Leapfrog is faster than RK4.", "leapfrog is faster than rk4", None),
    ("Symplectic Euler is faster than Euler.", "symplectic_euler is faster than euler", None),  # not "euler"
    ("Its peak is less than half of Forest–Ruth's.", "smaller than forest_ruth's, less than half", None),
    ("RK4 is faster.", "rk4 is more accurate than heun", None),  # another pivot: nothing to say
])
def test_the_subjects_of_a_comparison_sit_where_the_claim_puts_them(sentence, statement, problem):
    from mslab.claims_order import reversed_comparisons

    found = reversed_comparisons(sentence, [statement])
    assert (found == []) if problem is None else (len(found) == 1 and problem in found[0]), found


UNITS = ("claim holds: [v] it drifts apart, blows up and grows  (moved = 1e-09 m, apart_by = 1 cm, "
         "first_time = 5 s, steps = 6, 6, ratios = 5.4, 21.4, median = 0.56, "
         "newton = 4.7 Newton iterations per frame)\n")
LISTS = "claim holds: [v] it drifts apart  (lost = 20, 10, 5 ms, dt = 0.1 ms, ratio = 0.087)\n"


@pytest.mark.parametrize("sentence", [
    "They are apart within 10 s.",              # 5 s
    "They are apart within 6000 ms.",           # converted: 5 s
    "It blows up within 6 steps.",              # steps = 6, 6
    "The losses are 5-20 ms.",                  # a list shares the unit after its last number
    "It grows more than three times.",          # ratios = 5.4, 21.4
    "It takes 4.7 Newton iterations.",          # a word between a number and its count noun
    "The positions moved 1e-9 m.",
])
def test_numbers_with_a_unit_that_the_values_of_that_unit_carry(tmp_path, sentence):
    output = LISTS if "losses" in sentence else UNITS
    assert findings(tmp_path, [f"{sentence} <!-- claim: v -->"], output=output) == []


@pytest.mark.parametrize("sentence, problem", [
    ("They are apart within 2 s.", "below 2: no printed value fits"),          # 1 cm and 1e-9 m are no time
    ("They are apart within 2000 ms.", "below 2000: no printed value fits"),
    ("It blows up within 3 steps.", "below 3: no printed value fits"),
    ("It grows less than three times.", "below 3: no printed value fits"),     # not the median's 0.56
    ("It took 2 Newton iterations.", "2: no printed value fits"),
    ("The step is about a tenth of the limit.", "'a tenth' (a share in"),    # 0.1 ms is no share
])
def test_numbers_with_a_unit_that_only_other_values_would_carry(tmp_path, sentence, problem):
    output = LISTS if "tenth" in sentence else UNITS
    found = findings(tmp_path, [f"{sentence} <!-- claim: v -->"], output=output)
    assert len(found) == 1 and problem in found[0], found


@pytest.mark.parametrize("lesson, right, wrong, problem", MUTATIONS)
def test_a_wrong_number_magnitude_or_comparative_in_a_lesson_is_caught(tmp_path, lesson, right, wrong,
                                                                       problem):
    """A number, a magnitude word, a comparative, a share word and a bound on a share edited in real lessons:
    each is listed."""
    nb = nbformat.read(ROOT / "lessons" / lesson, as_version=4)
    assert lessons_check.check_notebook(ROOT / "lessons" / lesson) == []
    cells = [c for c in nb.cells if c.cell_type == "markdown" and right in c.source]
    assert len(cells) == 1
    cells[0].source = cells[0].source.replace(right, wrong)
    nbformat.write(nb, tmp_path / lesson)
    found = [str(f) for f in lessons_check.check_notebook(tmp_path / lesson)]
    assert len(found) == 1 and " ".join(wrong.split()) in found[0] and problem in found[0], found
