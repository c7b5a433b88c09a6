"""mslab.exercise_cells: one line for a student's cell (not done yet, right, a hint), never a traceback."""

import re
from pathlib import Path

import nbformat
import pytest

from mslab.exercise_cells import TODO, check_function, check_prediction, check_value


def euler(f, y, h):
    return y + h * f(y)


def backward(f, y, h):          # a common mistake: f at the new point
    return y + h * f(y + h * f(y))


CASES = [(lambda y: -2.0 * y, 1.0, 0.1), (lambda y: y * y, 0.5, 0.2)]


@pytest.mark.parametrize("fn, first, ok", [
    (lambda f, y, h: TODO, "not done yet: replace TODO in euler_step", False),
    (euler, "right: euler_step agrees with the reference on 2 case(s)", True),
    (backward, "not yet right: you evaluated f at the new point", False),
    (lambda f, y, h: y - h * f(y), "not yet right: euler_step differs from the reference", False),
    (lambda f, y, h: 1 / 0, "not yet right: euler_step", False),
])
def test_check_function_says_one_line(capsys, fn, first, ok):
    check_function("euler_step", fn, reference=euler, cases=CASES,
                   mistakes={"you evaluated f at the new point": backward})
    out = capsys.readouterr().out
    assert out.startswith("right") is ok
    assert out.startswith(first) and out.count("\n") == 1 and "Traceback" not in out


def test_check_value_and_prediction(capsys):
    check_value("the local error", TODO, 0.005)
    check_value("the local error", 0.005, 0.005)
    check_value("the local error", 0.05, 0.005, mistakes={"h, not h squared": 0.05})
    check_prediction(TODO, measured="grows", choices=("grows", "decays"))
    check_prediction(" Grows", measured="grows", choices=("grows", "decays"))
    check_prediction("decays", measured="grows", choices=("grows", "decays"))
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines] == ["not done yet", "right", "not yet right",
                                                      "not done yet", "right", "not yet right"]
    assert lines[2] == "not yet right: h, not h squared"
    assert "grows" not in lines[3].split("one of")[0] and lines[3].count("grows") == 1  # only as a choice


def test_check_value_compares_a_tableau_of_rows_and_weights(capsys):
    midpoint = [[[0.0, 0.0], [0.5, 0.0]], [0.0, 1.0]]
    heun = [[[0.0, 0.0], [1.0, 0.0]], [0.5, 0.5]]
    check_value("the tableau", [[[0, 0], [0.5, 0]], [0, 1]], midpoint)
    check_value("the tableau", heun, midpoint, mistakes={"that is Heun's": heun})
    check_value("the tableau", [[[0, 0], [0.5, 0]]], midpoint)
    assert capsys.readouterr().out.splitlines()[1] == "not yet right: that is Heun's"


def test_complex_answers_are_compared(capsys):
    check_function("R", lambda z: 1 / (1 - z), reference=lambda z: complex(1 / (1 - z)),
                   cases=[(2j,), (-0.5 + 0j,)], mistakes={"forward Euler's": lambda z: 1 + z})
    check_function("R", lambda z: 1 + z, reference=lambda z: 1 / (1 - z), cases=[(2j,), (-0.5 + 0j,)],
                   mistakes={"forward Euler's": lambda z: 1 + z})
    assert capsys.readouterr().out.splitlines() == ["right: R agrees with the reference on 2 case(s)",
                                                    "not yet right: forward Euler's"]


LESSONS = sorted((Path(__file__).resolve().parents[1] / "lessons").glob("[0-9][0-9]_*.ipynb"))


@pytest.mark.parametrize("path", LESSONS, ids=[p.stem for p in LESSONS])
def test_each_lesson_has_a_prediction_a_cell_to_complete_and_a_folded_derivation(path):
    """Stored unsolved: the student's TODO and the check's 'not done yet' line, never a solution."""
    nb = nbformat.read(path, as_version=4)
    markdown = "\n".join(c.source for c in nb.cells if c.cell_type == "markdown")
    code = [c for c in nb.cells if c.cell_type == "code"]
    shown = ["".join(o.get("text", "") for o in c.outputs) for c in code]
    assert "**Predict, then run.**" in markdown
    assert "**Complete a cell.**" in markdown or "**In code.**" in markdown
    assert re.search(r"<details><summary>Solution.*?</details>", markdown, re.DOTALL)
    assert sum("not done yet: write your prediction" in s for s in shown) >= 1
    assert sum(s.startswith("not done yet: replace TODO") for s in shown) >= 1
    assert not any(s.startswith("right:") for s in shown)


@pytest.mark.parametrize("path", LESSONS, ids=[p.stem for p in LESSONS])
def test_no_widget_draws_while_it_is_built(path):
    """interactive() runs its function at construction: in a headless nbclient run that cell waited for
    the whole cell timeout (lesson 01, 60 s). Sliders draw on change instead."""
    nb = nbformat.read(path, as_version=4)
    assert not any("widgets.interactive(" in c.source for c in nb.cells if c.cell_type == "code")
