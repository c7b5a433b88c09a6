"""Public tests of exercise 05 (run them from the folder above: ``pytest 05_verlet_leapfrog``)."""

import numpy as np
import pytest

from mslab.grading.checks import check_known, check_shape, reference_run
from mslab.grading.expected import Expected
from mslab.grading.problems import problem

MODULE = "verlet_leapfrog"
EXPECTED = Expected(__file__)  # the answers of wrong start-ups and steps (expected.json)
DT = 0.01  # the step of every test (defined once)


def start_state(seed=3):
    prob = problem("chain", n=5, dim=2, stiffness=40.0, sag=0.2)
    v0 = np.random.default_rng(seed).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    return prob, v0


def library_start(method, h=DT):
    """The start state, and the library's start-up of ``method``: Verlet's x_prev or leapfrog's v_half."""
    prob, v0 = start_state()
    return prob, prob.x0, reference_run(method, prob, prob.x0, v0, h, steps=0).memory[0], h


@pytest.mark.points(2)
def test_verlet_start_is_the_backward_taylor_step(student):
    prob, v0 = start_state()
    ref = reference_run("verlet", prob, prob.x0, v0, DT, steps=0)
    x_prev = student.verlet_start(prob.x0, v0, prob, DT)
    check_known((x_prev,), (ref.memory[0],), EXPECTED.arrays("verlet_start")[1], whats=("x_prev",))


@pytest.mark.points(2)
def test_verlet_steps_match_the_library(student):
    # from the library's start-up: a wrong verlet_start fails only the test above
    prob, v0 = start_state()
    _, x, x_prev, _ = library_start("verlet")
    ref = reference_run("verlet", prob, prob.x0, v0, DT, steps=5)
    wrong = EXPECTED.arrays("verlet_steps")[1]
    for _ in range(5):
        x, x_prev = student.verlet_step(x, x_prev, prob, DT), x
    check_known((x,), (ref.x,), wrong, whats=("x after 5 steps",), rtol=1e-10, atol=1e-12)


@pytest.mark.points(1)
def test_leapfrog_start_is_half_an_euler_step(student):
    prob, v0 = start_state()
    start = reference_run("leapfrog", prob, prob.x0, v0, DT, steps=0)
    check_known((student.leapfrog_start(prob.x0, v0, prob, DT),), (start.memory[0],), whats=("v_half",),
                mistakes={**EXPECTED.arrays("leapfrog_start")[1],
                          "the start velocity itself: v_1/2 needs half a step of a_0": (v0,)})


@pytest.mark.points(1)
def test_leapfrog_steps_match_the_library(student):
    # from the library's start-up: a wrong leapfrog_start fails only the test above
    prob, v0 = start_state()
    _, x, vh, _ = library_start("leapfrog")
    ref = reference_run("leapfrog", prob, prob.x0, v0, DT, steps=5)
    wrong = EXPECTED.arrays("leapfrog_steps")[1]
    for _ in range(5):
        out = student.leapfrog_step(x, vh, prob, DT)
        assert isinstance(out, tuple | list) and len(out) == 2, "return (x_next, v_half_next)"
        x, vh = out
    check_shape(x, prob.x0.shape, what="x")
    check_known((x, vh), (ref.x, ref.memory[0]), wrong, whats=("x after 5 steps", "v_half after 5 steps"),
                rtol=1e-10, atol=1e-12)
