"""Public tests of exercise 04 (run them from the folder above: ``pytest 04_rk4_tableau``)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, check_known, check_shape, reference_run
from mslab.grading.expected import Expected
from mslab.grading.problems import problem
from mslab.integrators import get_method

MODULE = "rk_tableau"
EXPECTED = Expected(__file__)  # the answers of stages built wrongly (expected.json)
RK4 = get_method("rk4")  # the library's RK4 (open: a graded file cannot import it)


def weights_hint(b):
    """The hint for RK4's weights in the wrong places, or all equal (None otherwise)."""
    if not isinstance(b, np.ndarray) or b.shape != (4,) or np.allclose(b, RK4.b):
        return None
    if np.allclose(np.sort(b), np.sort(RK4.b)):
        return "the weights misordered: the two middle stages count twice as much as the first and last"
    if np.allclose(b, 0.25):
        return "equal weights: RK4's four stages do not count equally"
    return None


def moving(prob, seed):
    """A start with every free particle moving: from rest several wrong stage rules take the right step."""
    return np.random.default_rng(seed).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]


def damped_chain():
    """The RK4 test's problem, start velocity and step (defined once)."""
    prob = problem("chain", n=5, dim=2, stiffness=60.0, gamma=0.2, sag=0.3)
    return prob, moving(prob, 41), 0.01


def short_chain():
    """The Euler and Heun test's problem, start velocity and step."""
    prob = problem("chain", n=3, dim=2, stiffness=30.0, sag=0.3)
    return prob, moving(prob, 42), 0.02


@pytest.mark.points(2)
def test_rk4_tableau_reproduces_the_stages_of_the_course(student):
    out = student.rk4_tableau()
    assert isinstance(out, tuple | list) and len(out) == 3, "return (A, b, c)"
    A, b, c = out
    check_shape(A, (4, 4), what="A")
    # the stages of eqs. 17-20 of the lecture notes, against the library's tableau
    check_array(A, RK4.A, what="A")
    weights = weights_hint(b)
    check_known((b,), (RK4.b,), {weights: (b,)} if weights else {}, whats=("b",))
    check_array(c, RK4.c, what="c")


@pytest.mark.points(3)
def test_rk_step_with_rk4_matches_the_library(student):
    (prob, v0, dt), rk4 = damped_chain(), RK4
    ref = reference_run("rk4", prob, prob.x0, v0, dt)
    x, v = student.rk_step(prob.x0, v0, prob, dt, rk4.A, rk4.b)
    check_known((x, v), (ref.x, ref.v), EXPECTED.arrays("rk4_chain")[1], whats=("x_new", "v_new"))


@pytest.mark.points(2)
def test_rk_step_with_euler_and_heun_tableaux(student):
    prob, v0, dt = short_chain()
    for name in ("euler", "heun"):
        method = get_method(name)
        ref = reference_run(name, prob, prob.x0, v0, dt)
        x, v = student.rk_step(prob.x0, v0, prob, dt, method.A, method.b)
        wrong = EXPECTED.arrays(f"{name}_chain")[1]
        check_known((x, v), (ref.x, ref.v), wrong, whats=(f"{name}: x_new", f"{name}: v_new"))
