"""Hidden tests of exercise 03 (graded, not released)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, reference_run, step_order
from mslab.grading.problems import problem

MODULE = "heun_midpoint"


def order_of(step):
    # a spring swinging sideways, drawn at grading time: nonlinear, no closed form to imitate
    return step_order(step, np.random.default_rng())


@pytest.mark.points(2)
def test_heun_is_second_order(student):
    order = order_of(student.heun_step)
    assert 1.8 < order < 2.3, f"observed order {order:.2f}, expected 2" + (
        " (an order-1 error: the corrector must average the slopes at both ends)" if order < 1.5 else "")


@pytest.mark.points(2)
def test_midpoint_is_second_order(student):
    order = order_of(student.midpoint_step)
    assert 1.8 < order < 2.3, f"observed order {order:.2f}, expected 2" + (
        " (an order-1 error: the step must use the slope at the half step)" if order < 1.5 else "")


@pytest.mark.points(2)
def test_both_in_3d_with_velocities(student):
    prob = problem("chain", n=4, dim=3, stiffness=40.0, gamma=1.0, sag=0.1)
    rng = np.random.default_rng(7)
    v0 = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    for name in ("heun", "midpoint"):
        ref = reference_run(name, prob, prob.x0, v0, 0.02, steps=3)
        x, v = prob.x0, v0
        for _ in range(3):
            x, v = getattr(student, f"{name}_step")(x, v, prob, 0.02)
        check_array(x, ref.x, rtol=1e-9, atol=1e-12, what=f"{name}: x after 3 steps")
        check_array(v, ref.v, rtol=1e-9, atol=1e-12, what=f"{name}: v after 3 steps")


@pytest.mark.points(1)
def test_both_on_a_chain_drawn_at_grading(student):
    # fresh inputs every grading: no table of answers can pass
    rng = np.random.default_rng()
    prob = problem("chain", n=int(rng.integers(3, 7)), dim=int(rng.integers(2, 4)),
                   stiffness=float(rng.uniform(20, 200)), gamma=float(rng.uniform(0, 1)), sag=0.3)
    v0 = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    dt = float(rng.uniform(1e-3, 1e-2))
    for name in ("heun", "midpoint"):
        ref = reference_run(name, prob, prob.x0, v0, dt)
        x, v = getattr(student, f"{name}_step")(prob.x0, v0, prob, dt)
        check_array(x, ref.x, rtol=1e-10, atol=1e-12, what=f"{name}: x_new")
        check_array(v, ref.v, rtol=1e-10, atol=1e-12, what=f"{name}: v_new")
