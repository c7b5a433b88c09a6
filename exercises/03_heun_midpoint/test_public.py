"""Public tests of exercise 03 (run them from the folder above: ``pytest 03_heun_midpoint``)."""

import numpy as np
import pytest

from mslab.grading.checks import check_known, check_shape, check_step, reference_run
from mslab.grading.expected import Expected
from mslab.grading.problems import problem
from mslab.state import State

MODULE = "heun_midpoint"
EXPECTED = Expected(__file__)  # the answers of steps with slopes at the wrong times (expected.json)
DT = 0.01  # the step on the moving chain (defined once)


def pair(out, shape):
    assert isinstance(out, tuple | list) and len(out) == 2, "return the pair (x_new, v_new)"
    check_shape(out[0], shape, what="x_new")
    check_shape(out[1], shape, what="v_new")
    return out


#: the common mistakes, as hint -> the method whose step that mistake takes
HINTS = {"midpoint": "this is the midpoint method's step: Heun averages the slopes at both ends",
         "heun": "this is Heun's step: the midpoint method uses the one slope at the half step",
         "euler": "one Euler step: the second slope is missing"}


def known(method, other, prob, v0):
    """The steps of common mistakes of ``method``: the other method's, Euler's, slopes at wrong times."""
    wrong = {hint: State(*out) for hint, out in EXPECTED.arrays(f"{method}_moving_chain")[1].items()}
    return {**{HINTS[m]: reference_run(m, prob, prob.x0, v0, DT) for m in (other, "euler")}, **wrong}


def moving_chain():
    """A damped chain with every free particle moving: from rest Heun and the midpoint
    method take the same step on it (position-only nonlinearity, linear drag)."""
    prob = problem("chain", n=5, dim=2, stiffness=60.0, gamma=0.3, sag=0.25)
    return prob, np.random.default_rng(31).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]


def swinging_spring():
    """An oscillator swinging sideways: the spring turns, so the problem is nonlinear (on a
    linear one, any oscillator along its axis, Heun and the midpoint method take exactly the
    same step and a test could not tell them apart)."""
    prob = problem("oscillator", stiffness=1.0, displacement=0.5, dim=2)
    return prob, prob.x0, np.array([[0.0, 0.0], [0.0, 0.8]]), 0.1


@pytest.mark.points(2)
def test_heun_on_a_swinging_spring(student):
    prob, x0, v0, h = swinging_spring()
    heun, midpoint = (reference_run(m, prob, x0, v0, h) for m in ("heun", "midpoint"))
    assert np.max(np.abs(midpoint.v - heun.v)) > 1e-6  # the midpoint answer fails this test
    x, v = pair(student.heun_step(x0, v0, prob, h), (2, 2))
    check_known((x, v), (heun.x, heun.v), {HINTS["midpoint"]: (midpoint.x, midpoint.v),
                                           **EXPECTED.arrays("swinging_spring")[1]},
                whats=("x_new", "v_new"))


@pytest.mark.points(2)
def test_heun_matches_the_library(student):
    prob, v0 = moving_chain()
    ref = reference_run("heun", prob, prob.x0, v0, DT)
    x, v = pair(student.heun_step(prob.x0, v0, prob, DT), (5, 2))
    check_step(x, v, ref, mistakes=known("heun", "midpoint", prob, v0))


@pytest.mark.points(2)
def test_midpoint_matches_the_library(student):
    prob, v0 = moving_chain()
    ref = reference_run("midpoint", prob, prob.x0, v0, DT)
    x, v = pair(student.midpoint_step(prob.x0, v0, prob, DT), (5, 2))
    check_step(x, v, ref, mistakes=known("midpoint", "heun", prob, v0))
