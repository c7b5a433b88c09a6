"""mslab.exercise_cells: one line for a student's cell (not done yet, right, a hint), never a traceback."""

import re
from pathlib import Path

import nbformat
import numpy as np
import pytest

from mslab import lesson_mistakes
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


# The "complete a cell" cells of lessons 06-09 and 11 once listed their wrong answers right under the
# student's TODO, each differing from the answer by the term its hint names (outside read 3, finding 6):
# the hints now come from mslab.lesson_mistakes, built from the cell's own reference.
HIDDEN_MISTAKES = {"06_energy_drift": "modified_energy", "07_work_precision": "evals_for",
                   "08_penalty_collisions": "dt_limit", "09_topology_and_volume": "bend_length",
                   "11_implicit_cloth": "newton_dv"}


def _completion_cell(stem):
    nb = nbformat.read(Path(__file__).resolve().parents[1] / "lessons" / f"{stem}.ipynb", as_version=4)
    cells = [c.source for c in nb.cells if c.cell_type == "code" and "TODO" in c.source
             and ("check_function(" in c.source or "check_value(" in c.source)]
    assert len(cells) == 1
    return cells[0]


@pytest.mark.parametrize("stem", sorted(HIDDEN_MISTAKES))
def test_completion_cell_does_not_list_its_wrong_answers(stem):
    source = _completion_cell(stem)
    assert "mistakes={" not in source and "lambda" not in source.split("check_")[-1]
    assert f"mistakes=common_mistakes.{HIDDEN_MISTAKES[stem]}(" in source


def _one_line(capsys, check, answer):
    check(answer)
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "Traceback" not in out
    return out.strip()


def test_modified_energy_mistakes_are_the_wrong_forms(capsys):
    right = lambda x, v, h, w: 0.5 * v * v + 0.5 * w * w * x * x - 0.5 * h * w * w * x * v  # noqa: E731
    hints = list(lesson_mistakes.modified_energy(right))
    cases = [(0.1, 0.3, 0.1, 1.0), (-0.2, 0.5, 0.05, 2.0), (1.0, -1.0, 0.3, 3.0)]
    def check(fn):
        check_function("H", fn, reference=right, cases=cases, mistakes=lesson_mistakes.modified_energy(right))
    energy = lambda x, v, h, w: 0.5 * v * v + 0.5 * w * w * x * x  # noqa: E731
    assert _one_line(capsys, check, right).startswith("right")
    assert _one_line(capsys, check, energy) == f"not yet right: {hints[0]}"
    assert _one_line(capsys, check, lambda x, v, h, w: energy(x, v, h, w) + 0.5 * h * w * w * x * v) == \
        f"not yet right: {hints[1]}"
    assert _one_line(capsys, check, lambda x, v, h, w: energy(x, v, h, w) - h * w * w * x * v) == \
        f"not yet right: {hints[2]}"


def test_evals_dt_limit_and_bend_length_mistakes(capsys):
    evals = lambda target, e0, n0, p: n0 * (e0 / target) ** (1 / p)  # noqa: E731
    wrong = [lambda t, e0, n0, p: n0 * (e0 / t) ** p, lambda t, e0, n0, p: n0 * (t / e0) ** (1 / p),
             lambda t, e0, n0, p: n0 * e0 / t]
    cases = [(1e-6, 8.9e-5, 800, 4), (1e-3, 4.1e-3, 400, 1), (1e-4, 3.7e-3, 401, 2)]
    limit = lambda m, k: 2 * (m / k) ** 0.5  # noqa: E731
    wrong_limits = [lambda m, k: (m / k) ** 0.5, lambda m, k: 2 * (k / m) ** 0.5,
                    lambda m, k: 3.141592653589793 * (m / k) ** 0.5, lambda m, k: 2 * m / k]
    bend = lambda h, phi: 2 * h * np.cos(phi / 2)  # noqa: E731
    wrong_bends = [lambda h, phi: 2 * h, lambda h, phi: 2 * h * np.sin(phi / 2),
                   lambda h, phi: 2 * h * np.cos(phi)]
    limit_cases = [(1.0, 1e4), (0.01, 2000.0), (2.0, 500.0)]
    for name, ref, wrongs, cs in [("evals_for", evals, wrong, cases),
                                  ("dt_limit", limit, wrong_limits, limit_cases),
                                  ("bend_length", bend, wrong_bends, [(0.1, 0.3), (1.0, 1.396), (0.5, 1.2)])]:
        table = getattr(lesson_mistakes, name)(ref)
        def check(fn, name=name, ref=ref, cs=cs, table=table):
            check_function(name, fn, reference=ref, cases=cs, mistakes=table)
        assert _one_line(capsys, check, ref).startswith("right")
        for hint, fn in zip(table, wrongs, strict=True):
            assert _one_line(capsys, check, fn) == f"not yet right: {hint}"
        assert _one_line(capsys, check, lambda *a: None).startswith(f"not yet right: {name} differs")


def test_newton_dv_mistakes_are_the_wrong_steps(capsys):
    m, k, c, h, u, v = 2.0, 50.0, 0.6, 0.1, 0.3, -0.4
    right = h * (-k * u - c * v - h * k * v) / (m + h * c + h * h * k)
    table = lesson_mistakes.newton_dv(m, k, c, h, u, v)
    wrong = [h * (-k * u - c * v) / (m + h * c + h * h * k),
             h * (-k * u - c * v - h * k * v) / (m - h * c - h * h * k), h * (-k * u - c * v) / m]
    def check(dv):
        check_value("dv", dv, right, rtol=1e-9, mistakes=table)
    assert _one_line(capsys, check, right).startswith("right")
    for hint, dv in zip(table, wrong, strict=True):
        assert _one_line(capsys, check, dv) == f"not yet right: {hint}"
    assert _one_line(capsys, check, "a string").startswith("not yet right: dv differs")
