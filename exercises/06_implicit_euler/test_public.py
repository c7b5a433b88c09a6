"""Public tests of exercise 06 (run them from the folder above: ``pytest 06_implicit_euler``)."""

import numpy as np
import pytest

from mslab.grading.checks import as_count, check_array, check_known, check_raises, check_shape
from mslab.grading.problems import problem

MODULE = "implicit_euler"


def stiff_chain(gamma=0.0):
    # k = 1e4 on a chain of mass 1: w ~ sqrt(k/m) ~ 200, explicit methods need dt < 0.005
    prob = problem("chain", n=6, dim=2, stiffness=1e4, gamma=gamma, sag=0.4)
    v0 = np.random.default_rng(6).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    return prob, v0


def triple(out, shape):
    assert isinstance(out, tuple | list) and len(out) == 3, "return (x_new, v_new, n_iter)"
    check_shape(out[0], shape, what="x_new")
    check_shape(out[1], shape, what="v_new")
    return out


def check_solves_implicit_euler(prob, x, v, x_new, v_new, dt, tol):
    # the defining equations of eq. 27 of the lecture notes, checked with the trusted acceleration
    check_array(x_new - x - dt * v_new, np.zeros_like(x), atol=tol, what="x_new - x - dt v_new")
    v_e = v + dt * prob(x, v)  # a common slip: the acceleration at the old state (an explicit step)
    explicit = {"an explicit step, with a(x, v) at the old state: implicit Euler solves for the new "
                "velocity": (v_e - v - dt * prob(x + dt * v_e, v_e),)}
    check_known((v_new - v - dt * prob(x_new, v_new),), (np.zeros_like(v),), explicit,
                whats=("v_new - v - dt a(x_new, v_new)",), atol=tol)


@pytest.mark.points(3)
def test_newton_solves_a_stiff_step(student):
    prob, v0 = stiff_chain(gamma=2.0)
    x, v, n_iter = triple(student.implicit_euler_newton(prob.x0, v0, prob, 0.01), prob.x0.shape)
    check_solves_implicit_euler(prob, prob.x0, v0, x, v, 0.01, 1e-8)
    # Newton's convergence is quadratic: a handful of corrections (the library's takes 5). Many more
    # solve the step too, slowly: the matrix is then not the Jacobian of g
    n_iter = as_count(n_iter, "n_iter")
    assert 1 <= n_iter <= 8, f"n_iter = {n_iter}, expected 1 to 8" + (
        ": likely mistake: Newton's matrix is missing a term (it is I - h (h K + D), with the drag's D)"
        if n_iter > 8 else "")


@pytest.mark.points(2)
def test_fixed_point_solves_a_small_step(student):
    prob, v0 = stiff_chain()
    x, v, n_iter = triple(student.implicit_euler_fixed_point(prob.x0, v0, prob, 2e-4), prob.x0.shape)
    check_solves_implicit_euler(prob, prob.x0, v0, x, v, 2e-4, 1e-8)
    assert isinstance(n_iter, int) and 1 <= n_iter <= 100, f"n_iter = {n_iter!r}"


@pytest.mark.points(2)
def test_fixed_point_refuses_a_large_step(student):
    # dt * w ~ 2 >> 1: the fixed-point map is no contraction; the same function solves a small step
    prob, v0 = stiff_chain()
    x, v, _ = triple(student.implicit_euler_fixed_point(prob.x0, v0, prob, 1e-4), prob.x0.shape)
    check_solves_implicit_euler(prob, prob.x0, v0, x, v, 1e-4, 1e-8)
    check_raises(RuntimeError, student.implicit_euler_fixed_point, prob.x0, v0, prob, 0.01)
