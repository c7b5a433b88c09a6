"""Public tests of exercise 02 (run them: ``pytest exercises/02_euler_steps``)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, check_shape, reference_run
from mslab.grading.problems import problem

MODULE = "euler_steps"


def one_step(student, name, prob, dt, x=None, v=None):
    x = prob.x0 if x is None else x
    v = prob.v0 if v is None else v
    out = getattr(student, name)(x, v, prob, dt)
    assert isinstance(out, tuple | list) and len(out) == 2, "return the pair (x_new, v_new)"
    check_shape(out[0], x.shape, what="x_new")
    check_shape(out[1], v.shape, what="v_new")
    return out


@pytest.mark.points(2)
def test_forward_euler_on_an_oscillator(student):
    prob = problem("oscillator", stiffness=4.0, displacement=0.3)
    x, v = one_step(student, "forward_euler_step", prob, 0.1)
    # x'' = -4 u from rest at u = 0.3: the position keeps still, the velocity gains -4*0.3*0.1
    check_array(x, prob.x0, what="x_new")
    check_array(v, np.array([[0.0], [-0.12]]), what="v_new")


@pytest.mark.points(2)
def test_symplectic_euler_matches_the_library(student):
    prob = problem("chain", n=4, dim=2, stiffness=50.0, sag=0.2)
    ref = reference_run("symplectic_euler", prob, prob.x0, prob.v0, 0.01)
    x, v = one_step(student, "symplectic_euler_step", prob, 0.01)
    check_array(x, ref.x, what="x_new")
    check_array(v, ref.v, what="v_new")


@pytest.mark.points(2)
def test_symplectic_euler_x_matches_the_library(student):
    prob = problem("chain", n=4, dim=2, stiffness=50.0, sag=0.2)
    ref = reference_run("symplectic_euler_x", prob, prob.x0, prob.v0, 0.01)
    x, v = one_step(student, "symplectic_euler_x_step", prob, 0.01)
    check_array(x, ref.x, what="x_new")
    check_array(v, ref.v, what="v_new")
