"""Public tests of exercise 05 (run them from the folder above: ``pytest 05_verlet_leapfrog``)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, check_shape, reference_run
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
    check_array(x_prev, ref.memory[0], what="x_prev")


@pytest.mark.points(2)
def test_verlet_steps_match_the_library(student):
    # from the library's start-up: a wrong verlet_start fails only the test above
    prob, v0 = start_state()
    x_prev, x = reference_run("verlet", prob, prob.x0, v0, 0.01, steps=0).memory[0], prob.x0
    ref = reference_run("verlet", prob, prob.x0, v0, 0.01, steps=5)
    for _ in range(5):
        x, x_prev = student.verlet_step(x, x_prev, prob, 0.01), x
    check_array(x, ref.x, rtol=1e-10, atol=1e-12, what="x after 5 steps")


@pytest.mark.points(1)
def test_leapfrog_start_is_half_an_euler_step(student):
    prob, v0 = start_state()
    start = reference_run("leapfrog", prob, prob.x0, v0, 0.01, steps=0)
    check_array(student.leapfrog_start(prob.x0, v0, prob, 0.01), start.memory[0], what="v_half")


@pytest.mark.points(1)
def test_leapfrog_steps_match_the_library(student):
    # from the library's start-up: a wrong leapfrog_start fails only the test above
    prob, v0 = start_state()
    x, vh = prob.x0, reference_run("leapfrog", prob, prob.x0, v0, 0.01, steps=0).memory[0]
    ref = reference_run("leapfrog", prob, prob.x0, v0, 0.01, steps=5)
    for _ in range(5):
        out = student.leapfrog_step(x, vh, prob, 0.01)
        assert isinstance(out, tuple | list) and len(out) == 2, "return (x_next, v_half_next)"
        x, vh = out
    check_shape(x, prob.x0.shape, what="x")
    check_array(x, ref.x, rtol=1e-10, atol=1e-12, what="x after 5 steps")
    check_array(vh, ref.memory[0], rtol=1e-10, atol=1e-12, what="v_half after 5 steps")
