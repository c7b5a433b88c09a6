"""Public tests of exercise 02 (run them from the folder above: ``pytest 02_euler_steps``)."""

import numpy as np
import pytest

from mslab.grading.checks import check_known, check_shape, check_step, reference_run
from mslab.grading.problems import problem
from mslab.state import State

MODULE = "euler_steps"


def one_step(student, name, prob, dt, x=None, v=None):
    x = prob.x0 if x is None else x
    v = prob.v0 if v is None else v
    out = getattr(student, name)(x, v, prob, dt)
    assert isinstance(out, tuple | list) and len(out) == 2, "return the pair (x_new, v_new)"
    check_shape(out[0], x.shape, what="x_new")
    check_shape(out[1], v.shape, what="v_new")
    return out


OLD_STATE = "the step returns the old state: x and v must both move"
#: the common mistakes of each step, as (hint, method whose step that mistake takes)
MISTAKES = {
    "symplectic_euler": lambda prob, v0, dt: {
        "the two symplectic Eulers are swapped (symplectic_euler_step updates v first, x with the new v)":
            reference_run("symplectic_euler_x", prob, prob.x0, v0, dt),
        "x moved with the old velocity (that is forward Euler)":
            reference_run("euler", prob, prob.x0, v0, dt),
        OLD_STATE: State(prob.x0, v0)},
    "symplectic_euler_x": lambda prob, v0, dt: {
        "the two symplectic Eulers are swapped (symplectic_euler_x_step updates x first, v at the new x)":
            reference_run("symplectic_euler", prob, prob.x0, v0, dt),
        "v updated at the old position (that is forward Euler)":
            reference_run("euler", prob, prob.x0, v0, dt),
        OLD_STATE: State(prob.x0, v0)},
}


def moving(prob, seed):
    """A start with every free particle moving: from rest, forward Euler and the
    position-first symplectic Euler take the same step (x_1 = x_0 either way)."""
    return np.random.default_rng(seed).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]


@pytest.mark.points(2)
def test_forward_euler_on_an_oscillator(student):
    prob = problem("oscillator", stiffness=4.0, displacement=0.3)
    v0 = np.array([[0.0], [0.5]])
    x, v = one_step(student, "forward_euler_step", prob, 0.1, v=v0)
    # x'' = -4 u at u = 0.3 moving at 0.5: x gains 0.1 * 0.5, v gains -4 * 0.3 * 0.1 (both from the old state)
    symplectic = reference_run("symplectic_euler", prob, prob.x0, v0, 0.1)
    known = {"x moved with the new velocity (that is symplectic Euler): forward Euler moves x and v from "
             "the old state": (symplectic.x, symplectic.v), OLD_STATE: (prob.x0, v0)}
    check_known((x, v), (prob.x0 + np.array([[0.0], [0.05]]), np.array([[0.0], [0.5 - 0.12]])), known,
                whats=("x_new", "v_new"))


@pytest.mark.points(2)
def test_symplectic_euler_matches_the_library(student):
    prob = problem("chain", n=4, dim=2, stiffness=50.0, sag=0.2)
    v0 = moving(prob, 21)
    ref = reference_run("symplectic_euler", prob, prob.x0, v0, 0.01)
    x, v = one_step(student, "symplectic_euler_step", prob, 0.01, v=v0)
    check_step(x, v, ref, mistakes=MISTAKES["symplectic_euler"](prob, v0, 0.01))


@pytest.mark.points(2)
def test_symplectic_euler_x_matches_the_library(student):
    prob = problem("chain", n=4, dim=2, stiffness=50.0, sag=0.2)
    v0 = moving(prob, 22)
    ref = reference_run("symplectic_euler_x", prob, prob.x0, v0, 0.01)
    x, v = one_step(student, "symplectic_euler_x_step", prob, 0.01, v=v0)
    check_step(x, v, ref, mistakes=MISTAKES["symplectic_euler_x"](prob, v0, 0.01))
