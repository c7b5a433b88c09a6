"""Hidden tests of exercise 06 (graded, not released)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, reference_run
from mslab.grading.problems import problem

MODULE = "implicit_euler"


@pytest.mark.points(2)
def test_newton_matches_the_library_with_drag(student):
    prob = problem("chain", n=5, dim=3, stiffness=5e3, gamma=2.0, sag=0.3)
    v0 = np.random.default_rng(9).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    ref = reference_run("implicit_euler", prob, prob.x0, v0, 0.02)
    x, v, _ = student.implicit_euler_newton(prob.x0, v0, prob, 0.02)
    check_array(x, ref.x, rtol=1e-8, atol=1e-9, what="x_new")
    check_array(v, ref.v, rtol=1e-8, atol=1e-8, what="v_new")


@pytest.mark.points(1)
def test_newton_needs_few_iterations(student):
    # a sagging stiff chain is nonlinear: one correction cannot solve it, a handful must
    prob = problem("chain", n=6, dim=2, stiffness=1e4, sag=0.4)
    x, v, n_iter = student.implicit_euler_newton(prob.x0, prob.v0, prob, 0.01)
    ref = reference_run("implicit_euler", prob, prob.x0, prob.v0, 0.01)
    check_array(x, ref.x, rtol=1e-8, atol=1e-9, what="x_new")
    check_array(v, ref.v, rtol=1e-8, atol=1e-8, what="v_new")
    assert isinstance(n_iter, int) and 2 <= n_iter <= 8, f"n_iter = {n_iter!r}: Newton should take 2 to 8"


@pytest.mark.points(2)
def test_fixed_point_and_newton_agree(student):
    prob = problem("chain", n=4, dim=2, stiffness=500.0, gamma=0.5, sag=0.2)
    xf, vf, _ = student.implicit_euler_fixed_point(prob.x0, prob.v0, prob, 1e-3)
    ref = reference_run("implicit_euler", prob, prob.x0, prob.v0, 1e-3)
    check_array(xf, ref.x, rtol=1e-8, atol=1e-9, what="x_new")
    check_array(vf, ref.v, rtol=1e-8, atol=1e-8, what="v_new")


@pytest.mark.points(1)
def test_newton_damps_a_stiff_oscillation(student):
    # R(z) = 1/(1 - z): every step shrinks the energy, even at dt * w ~ 10 (drawn at grading time);
    # on the oscillator implicit Euler is linear: (u, v) -> inv([[1, -h], [w^2 h, 1]]) (u, v)
    rng = np.random.default_rng()
    k, h = float(rng.uniform(50.0, 200.0)), float(rng.uniform(0.5, 1.5))
    prob = problem("oscillator", stiffness=k, displacement=0.3)
    M = np.linalg.inv(np.array([[1.0, -h], [k * h, 1.0]]))
    x, v, y = prob.x0, prob.v0, np.array([0.3, 0.0])
    amplitude = []
    for n in range(10):
        x, v, _ = student.implicit_euler_newton(x, v, prob, h)
        y = M @ y
        amplitude.append(np.hypot(float(x[1, 0]) - 1.0, float(v[1, 0]) / np.sqrt(k)))
        if n < 3:  # while the state is far above round-off: implicit Euler's own phase and decay
            check_array(np.array([float(x[1, 0]) - 1.0, float(v[1, 0])]), y, rtol=1e-7, atol=1e-12,
                        what=f"(u, v) after {n + 1} steps")
    assert np.all(np.diff(amplitude) < 0) and amplitude[-1] < 0.3 * 0.2, "the oscillation must decay"


@pytest.mark.points(1)
def test_newton_on_a_chain_drawn_at_grading(student):
    # fresh inputs every grading: no table of answers can pass
    rng = np.random.default_rng()
    prob = problem("chain", n=int(rng.integers(3, 7)), dim=2, stiffness=float(rng.uniform(1e3, 1e4)),
                   gamma=float(rng.uniform(0, 2)), sag=0.3)
    v0 = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    dt = float(rng.uniform(5e-3, 2e-2))
    ref = reference_run("implicit_euler", prob, prob.x0, v0, dt)
    x, v, _ = student.implicit_euler_newton(prob.x0, v0, prob, dt)
    check_array(x, ref.x, rtol=1e-8, atol=1e-9, what="x_new")
    check_array(v, ref.v, rtol=1e-8, atol=1e-8, what="v_new")
