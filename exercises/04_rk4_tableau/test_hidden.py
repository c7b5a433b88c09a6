"""Hidden tests of exercise 04 (graded, not released)."""

import numpy as np
import pytest

from mslab.grading.checks import as_numbers, check_array, reference_run, step_order
from mslab.grading.problems import problem
from mslab.integrators import ExplicitRK, get_method
from mslab.state import State

MODULE = "rk_tableau"


# first: the tests of a group share one sandbox, and the next tests hand RK4's tableau to the
# student's rk_step (a file could keep it and return it from rk4_tableau)
@pytest.mark.points(1)
def test_student_rk4_tableau_drives_the_library(student):
    out = student.rk4_tableau()
    assert isinstance(out, tuple | list) and len(out) == 3, "return (A, b, c)"
    # only numbers reach the library: no text of the student's is parsed in the grader
    A, b, c = as_numbers(out[0], (4, 4), "A"), as_numbers(out[1], (4,), "b"), as_numbers(out[2], (4,), "c")
    prob = problem("chain", n=3, dim=2, stiffness=30.0, sag=0.3)
    ref = reference_run("rk4", prob, prob.x0, prob.v0, 0.05)
    mine = ExplicitRK(A, b, c).step(prob.system(), State(prob.x0, prob.v0), 0.05)
    check_array(mine.x, ref.x, what="x_new from your tableau")


@pytest.mark.points(2)
def test_rk4_through_the_stepper_is_fourth_order(student):
    A, b = get_method("rk4").A, get_method("rk4").b
    # a spring swinging sideways, drawn at grading time: nonlinear, no closed form to imitate
    order = step_order(student.rk_step, np.random.default_rng(), A, b)
    assert 3.7 < order < 4.4, f"observed order {order:.2f}, expected 4"


@pytest.mark.points(2)
def test_any_five_stage_tableau(student):
    rng = np.random.default_rng(4)
    A = np.tril(rng.uniform(-1, 1, (5, 5)), k=-1)
    b = rng.uniform(0, 1, 5)
    prob = problem("chain", n=4, dim=3, stiffness=25.0, gamma=0.4, sag=0.2)
    system = prob.system()
    ref = ExplicitRK(A, b).step(system, State(prob.x0, prob.v0), 0.03)
    x, v = student.rk_step(prob.x0, prob.v0, prob, 0.03, A, b)
    check_array(x, ref.x, rtol=1e-9, atol=1e-12, what="x_new")
    check_array(v, ref.v, rtol=1e-9, atol=1e-12, what="v_new")


@pytest.mark.points(1)
def test_a_tableau_drawn_at_grading(student):
    # fresh tableau and state every grading: no table of answers can pass
    rng = np.random.default_rng()
    s = int(rng.integers(2, 6))
    A = np.tril(rng.uniform(-1, 1, (s, s)), k=-1)
    b = rng.uniform(0, 1, s)
    prob = problem("chain", n=int(rng.integers(3, 6)), dim=2, stiffness=float(rng.uniform(10, 80)), sag=0.2)
    v0 = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    ref = ExplicitRK(A, b).step(prob.system(), State(prob.x0, v0), 0.02)
    x, v = student.rk_step(prob.x0, v0, prob, 0.02, A, b)
    check_array(x, ref.x, rtol=1e-9, atol=1e-12, what="x_new")
    check_array(v, ref.v, rtol=1e-9, atol=1e-12, what="v_new")
