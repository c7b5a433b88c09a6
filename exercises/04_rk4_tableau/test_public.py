"""Public tests of exercise 04 (run them from the folder above: ``pytest 04_rk4_tableau``)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, check_known, check_shape, reference_run
from mslab.grading.expected import Expected
from mslab.grading.problems import problem
from mslab.integrators import get_method

MODULE = "rk_tableau"
EXPECTED = Expected(__file__)  # the answers of stages built wrongly (expected.json)
RK4_B = np.array([1, 2, 2, 1]) / 6


def weights_hint(b):
    """The hint for RK4's weights in the wrong places, or all equal (None otherwise)."""
    if not isinstance(b, np.ndarray) or b.shape != (4,) or np.allclose(b, RK4_B):
        return None
    if np.allclose(np.sort(b), np.sort(RK4_B)):
        return "the weights misordered: RK4's are 1/6, 1/3, 1/3, 1/6 (the two middle stages count twice)"
    if np.allclose(b, 0.25):
        return "equal weights: RK4's are 1/6, 1/3, 1/3, 1/6 (the two middle stages count twice)"
    return None


def damped_chain():
    return problem("chain", n=5, dim=2, stiffness=60.0, gamma=0.2, sag=0.3)


def short_chain():
    return problem("chain", n=3, dim=2, stiffness=30.0, sag=0.3)


@pytest.mark.points(2)
def test_rk4_tableau_reproduces_the_stages_of_the_course(student):
    out = student.rk4_tableau()
    assert isinstance(out, tuple | list) and len(out) == 3, "return (A, b, c)"
    A, b, c = out
    check_shape(A, (4, 4), what="A")
    # eqs. 17-20 of the lecture notes: each stage starts from y_n plus h/2, h/2, h times the previous slope
    expected = np.zeros((4, 4))
    expected[1, 0], expected[2, 1], expected[3, 2] = 0.5, 0.5, 1.0
    check_array(A, expected, what="A")
    weights = weights_hint(b)
    check_known((b,), (RK4_B,), {weights: (b,)} if weights else {}, whats=("b",))
    check_array(c, np.array([0.0, 0.5, 0.5, 1.0]), what="c")


@pytest.mark.points(3)
def test_rk_step_with_rk4_matches_the_library(student):
    prob, rk4 = damped_chain(), get_method("rk4")
    ref = reference_run("rk4", prob, prob.x0, prob.v0, 0.01)
    x, v = student.rk_step(prob.x0, prob.v0, prob, 0.01, rk4.A, rk4.b)
    check_known((x, v), (ref.x, ref.v), EXPECTED.arrays("rk4_chain")[1], whats=("x_new", "v_new"))


@pytest.mark.points(2)
def test_rk_step_with_euler_and_heun_tableaux(student):
    prob = short_chain()
    for name in ("euler", "heun"):
        method = get_method(name)
        ref = reference_run(name, prob, prob.x0, prob.v0, 0.02)
        x, v = student.rk_step(prob.x0, prob.v0, prob, 0.02, method.A, method.b)
        wrong = EXPECTED.arrays(f"{name}_chain")[1]
        check_known((x, v), (ref.x, ref.v), wrong, whats=(f"{name}: x_new", f"{name}: v_new"))
