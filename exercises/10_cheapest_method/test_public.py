"""Public tests of exercise 10 (run them from the folder above: ``pytest 10_cheapest_method``)."""

import pytest

from mslab.grading.checks import as_count, check_scalar
from mslab.grading.expected import Expected

MODULE = "cheapest_method"
EXPECTED = Expected(__file__)  # the right answers and the known mistakes' answers, as numbers (expected.json)

DTS = [0.2, 0.1, 0.05, 0.025]


def exact_power_law():
    """Errors e = 0.7 h^2.5 exactly: (dts, errors)."""
    return DTS, [0.7 * h**2.5 for h in DTS]


def noisy_power_law():
    """Errors e = 3 h, each off by up to 20 %: (dts, errors)."""
    return DTS, [3.0 * h * (1 + 0.2 * s) for h, s in zip(DTS, (0.5, -1.0, 0.8, -0.3), strict=True)]


def one_method():
    """A method with the error model e = 3 h^2, and the error target 1e-4: (C, p, target)."""
    return 3.0, 2.0, 1e-4


@pytest.mark.points(2)
def test_fit_recovers_an_exact_and_a_noisy_power_law(student):
    C, p = student.fit_error_model(*exact_power_law())
    check_scalar(C, 0.7, rtol=1e-9, what="C", mistakes={
        **EXPECTED.scalar("exact_power_law_C")[1], "(C, p) swapped: the slope is p": 2.5})
    check_scalar(p, 2.5, rtol=1e-9, what="p")
    (p_fit, c_fit), _ = EXPECTED.arrays("noisy_power_law")  # the least-squares fit (p, C)
    C, p = student.fit_error_model(*noisy_power_law())
    check_scalar(p, p_fit, rtol=1e-9, what="p (least squares)")
    check_scalar(C, c_fit, rtol=1e-9, what="C (least squares)")


@pytest.mark.points(2)
def test_step_and_cost_of_one_method(student):
    h = student.step_for_target(*one_method())
    right, wrong = EXPECTED.scalar("step_for_target")
    check_scalar(h, right, rtol=1e-12, what="h", mistakes=wrong)
    # t_end / h = 173.2: the run needs 174 steps (173 would be a larger step, more error than asked)
    n_steps, n_force = student.predicted_cost(right, 1.0, 4, 1)
    got = (as_count(n_steps, "n_steps"), as_count(n_force, "n_force"))
    hint = {(173, 693): "t_end / h = 173.2 rounded down: 173 steps are a larger step, take the ceiling",
            (174, 696): "the start-up evaluation is missing: n_steps * evals_per_step + start_evals"}
    assert got == (174, 697), f"(n_steps, n_force) = {(n_steps, n_force)}, expected (174, 697)" + (
        f": likely mistake: {hint[got]}" if got in hint else "")


@pytest.mark.points(2)
def test_loose_target_goes_to_low_order_and_tight_to_high_order(student):
    dts = [0.1, 0.05, 0.025]
    runs = {"first": {"dts": dts, "errors": [0.05 * h for h in dts], "evals_per_step": 1,
                      "start_evals": 0},
            "fourth": {"dts": dts, "errors": [2.0 * h**4 for h in dts], "evals_per_step": 4,
                       "start_evals": 0}}
    # 'first': h = 0.26, 4 steps, 4 evaluations; 'fourth': h = 0.284, 4 steps, 16 evaluations
    name, n_steps, n_force = student.cheapest(runs, 1.3e-2, 1.0)
    assert name == "first", f"loose target 1.3e-2: chose {name!r}"
    assert (as_count(n_steps, "n_steps"), as_count(n_force, "n_force")) == (4, 4), \
        f"(n_steps, n_force) = {(n_steps, n_force)}, expected (4, 4)"
    name, n_steps, n_force = student.cheapest(runs, 1e-6, 1.0)
    # 'first' needs 50000 steps; 'fourth' reaches the target at h = 0.0266: 38 steps, 152 evaluations
    assert name == "fourth", f"tight target 1e-6: chose {name!r}"
    assert (as_count(n_steps, "n_steps"), as_count(n_force, "n_force")) == (38, 152), \
        f"(n_steps, n_force) = {(n_steps, n_force)}, expected (38, 152)"
