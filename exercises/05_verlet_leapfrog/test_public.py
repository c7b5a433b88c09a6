"""Public tests of exercise 05 (run them from the folder above: ``pytest 05_verlet_leapfrog``)."""

import numpy as np
import pytest

from mslab.grading import mistakes
from mslab.grading.checks import check_known, check_shape, reference_run
from mslab.grading.problems import problem

MODULE = "verlet_leapfrog"


def start_state(seed=3):
    prob = problem("chain", n=5, dim=2, stiffness=40.0, sag=0.2)
    v0 = np.random.default_rng(seed).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    return prob, v0


@pytest.mark.points(2)
def test_verlet_start_is_the_backward_taylor_step(student):
    prob, v0 = start_state()
    ref = reference_run("verlet", prob, prob.x0, v0, 0.01, steps=0)
    x_prev = student.verlet_start(prob.x0, v0, prob, 0.01)
    h, a0 = 0.01, prob(prob.x0)
    rule = "(x_-1 = x_0 - h v_0 + h^2/2 a_0)"
    check_known((x_prev,), (ref.memory[0],), whats=("x_prev",), mistakes={
        f"the h^2/2 a term is missing {rule}": (prob.x0 - h * v0,),
        f"a forward step, not a backward one {rule}": (prob.x0 + h * v0 + h * h / 2 * a0,),
        f"the sign of the h^2/2 a term {rule}": (prob.x0 - h * v0 - h * h / 2 * a0,)})


@pytest.mark.points(2)
def test_verlet_steps_match_the_library(student):
    # from the library's start-up: a wrong verlet_start fails only the test above
    prob, v0 = start_state()
    x_prev, x = reference_run("verlet", prob, prob.x0, v0, 0.01, steps=0).memory[0], prob.x0
    ref = reference_run("verlet", prob, prob.x0, v0, 0.01, steps=5)
    wrong = mistakes.verlet_leapfrog("verlet", prob, x, x_prev, 0.01, steps=5)
    for _ in range(5):
        x, x_prev = student.verlet_step(x, x_prev, prob, 0.01), x
    check_known((x,), (ref.x,), wrong, whats=("x after 5 steps",), rtol=1e-10, atol=1e-12)


@pytest.mark.points(1)
def test_leapfrog_start_is_half_an_euler_step(student):
    prob, v0 = start_state()
    start = reference_run("leapfrog", prob, prob.x0, v0, 0.01, steps=0)
    h, a0 = 0.01, prob(prob.x0)
    check_known((student.leapfrog_start(prob.x0, v0, prob, h),), (start.memory[0],), whats=("v_half",),
                mistakes={"a whole Euler step, not half of one (v_1/2 = v_0 + h/2 a_0)": (v0 + h * a0,),
                          "the start velocity itself: v_1/2 needs half a step of a_0": (v0,)})


@pytest.mark.points(1)
def test_leapfrog_steps_match_the_library(student):
    # from the library's start-up: a wrong leapfrog_start fails only the test above
    prob, v0 = start_state()
    x, vh = prob.x0, reference_run("leapfrog", prob, prob.x0, v0, 0.01, steps=0).memory[0]
    ref = reference_run("leapfrog", prob, prob.x0, v0, 0.01, steps=5)
    wrong = mistakes.verlet_leapfrog("leapfrog", prob, x, vh, 0.01, steps=5)
    for _ in range(5):
        out = student.leapfrog_step(x, vh, prob, 0.01)
        assert isinstance(out, tuple | list) and len(out) == 2, "return (x_next, v_half_next)"
        x, vh = out
    check_shape(x, prob.x0.shape, what="x")
    check_known((x, vh), (ref.x, ref.memory[0]), wrong, whats=("x after 5 steps", "v_half after 5 steps"),
                rtol=1e-10, atol=1e-12)
