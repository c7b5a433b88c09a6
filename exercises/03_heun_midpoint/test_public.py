"""Public tests of exercise 03 (run them: ``pytest exercises/03_heun_midpoint``)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, check_shape, reference_run
from mslab.grading.problems import problem

MODULE = "heun_midpoint"


def pair(out, shape):
    assert isinstance(out, tuple | list) and len(out) == 2, "return the pair (x_new, v_new)"
    check_shape(out[0], shape, what="x_new")
    check_shape(out[1], shape, what="v_new")
    return out


@pytest.mark.points(2)
def test_heun_on_an_oscillator_by_hand(student):
    # u'' = -u from u = 0.5 at rest, h = 0.1: u1 = 0.5 (1 - h^2/2), u1' = -0.5 h
    prob = problem("oscillator", stiffness=1.0, displacement=0.5)
    x, v = pair(student.heun_step(prob.x0, prob.v0, prob, 0.1), (2, 1))
    check_array(x, np.array([[0.0], [1.0 + 0.5 * (1 - 0.005)]]), what="x_new")
    check_array(v, np.array([[0.0], [-0.05]]), what="v_new")


@pytest.mark.points(2)
def test_heun_matches_the_library(student):
    prob = problem("chain", n=5, dim=2, stiffness=60.0, gamma=0.3, sag=0.25)
    ref = reference_run("heun", prob, prob.x0, prob.v0, 0.01)
    x, v = pair(student.heun_step(prob.x0, prob.v0, prob, 0.01), (5, 2))
    check_array(x, ref.x, what="x_new")
    check_array(v, ref.v, what="v_new")


@pytest.mark.points(2)
def test_midpoint_matches_the_library(student):
    prob = problem("chain", n=5, dim=2, stiffness=60.0, gamma=0.3, sag=0.25)
    ref = reference_run("midpoint", prob, prob.x0, prob.v0, 0.01)
    x, v = pair(student.midpoint_step(prob.x0, prob.v0, prob, 0.01), (5, 2))
    check_array(x, ref.x, what="x_new")
    check_array(v, ref.v, what="v_new")
