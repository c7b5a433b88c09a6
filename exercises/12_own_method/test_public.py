"""Public tests of exercise 12 (run them from the folder above: ``pytest 12_own_method``)."""

from fractions import Fraction as Fr

import numpy as np
import pytest

from mslab import ExplicitRK
from mslab.derive import order
from mslab.grading.checks import as_numbers, check_array, check_known
from mslab.grading.expected import Expected
from mslab.grading.problems import problem
from mslab.state import State

MODULE = "own_method"
EXPECTED = Expected(__file__)  # the answers of known mistakes (expected.json)
DT = 0.01  # the step of the rk3 test (defined once)

KUTTA3 = (np.array([[0, 0, 0], [0.5, 0, 0], [-1, 2, 0]], dtype=float), np.array([1 / 6, 2 / 3, 1 / 6]))
HEUN3 = (np.array([[0, 0, 0], [1 / 3, 0, 0], [0, 2 / 3, 0]], dtype=float), np.array([0.25, 0.0, 0.75]))


def tableau(out):
    assert isinstance(out, tuple | list) and len(out) == 2, "return (A, b)"
    A, b = as_numbers(out[0], (3, 3), what="A"), as_numbers(out[1], (3,), what="b")
    assert np.all(np.triu(A) == 0.0), "A must be strictly lower triangular (an explicit method)"
    return A, b


def moving_chain():
    prob = problem("chain", n=4, dim=2, stiffness=50.0, gamma=0.3, sag=0.2)
    return prob, np.random.default_rng(12).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]


@pytest.mark.points(2)
def test_residuals_of_kutta_and_of_a_second_order_method(student):
    A, b = KUTTA3
    check_known((student.order3_conditions(A, b),), (np.zeros(4),), whats=("Kutta's residuals",), atol=1e-14,
                mistakes=EXPECTED.arrays("kutta_column_nodes")[1])
    # Heun's second-order method (two stages): order 2 holds, the two order-3 conditions fail
    A = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([0.5, 0.5])
    check_array(student.order3_conditions(A, b), [0.0, 0.0, 0.5 - 1 / 3, -1 / 6], atol=1e-14,
                what="Heun's residuals")


@pytest.mark.points(2)
def test_kutta_family_gives_kutta_and_heun3(student):
    for (c2, c3), (A, b) in (((0.5, 1.0), KUTTA3), ((1 / 3, 2 / 3), HEUN3)):
        got_A, got_b = tableau(student.kutta_family(c2, c3))
        check_array(got_A, A, atol=1e-13, what=f"A at c2 = {c2:.3g}, c3 = {c3:.3g}")
        check_known((got_b,), (b,), whats=(f"b at c2 = {c2:.3g}, c3 = {c3:.3g}",), atol=1e-13,
                    mistakes={"b2 and b3 swapped: b2 goes with the node c2": (b[[0, 2, 1]],)})


@pytest.mark.points(1)
def test_rk3_step_with_kutta_matches_the_library(student):
    # one step of Kutta's tableau on a moving, damped chain against the library's stepping of it
    prob, v0 = moving_chain()
    A, b = KUTTA3
    ref = ExplicitRK(A, b, name="kutta").step(prob.system(), State(prob.x0.copy(), v0.copy()), DT)
    out = student.rk3_step(prob.x0, v0, prob, DT, A, b)
    assert isinstance(out, tuple | list) and len(out) == 2, "return (x_new, v_new)"
    check_known(tuple(out), (ref.x, ref.v), EXPECTED.arrays("kutta_step")[1], whats=("x_new", "v_new"))


@pytest.mark.points(2)
def test_my_method_has_derived_order_three(student):
    A, b = tableau(student.my_method())
    p = order(ExplicitRK(A, b, name="student"))
    assert p == 3, f"derived order {p}, expected 3"
    known = {"SSPRK3": [1, Fr(1, 2)], "Kutta's": [Fr(1, 2), 1], "Heun's": [Fr(1, 3), Fr(2, 3)],
             "Ralston's": [Fr(1, 2), Fr(3, 4)]}
    for name, nodes in known.items():
        assert not np.allclose(A.sum(axis=1)[1:], np.array(nodes, dtype=float)), \
            f"these are the nodes of {name} method (lesson 10): choose your own"
