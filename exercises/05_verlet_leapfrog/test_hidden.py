"""Hidden tests of exercise 05 (graded, not released)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, observed_order, reference_run, swinging_spring
from mslab.grading.problems import problem

MODULE = "verlet_leapfrog"


def verlet(student, prob, v0, dt, n, start=None):
    """n Verlet steps; from ``start`` (the library's x_prev) when given, else the student's start-up."""
    x_prev = student.verlet_start(prob.x0, v0, prob, dt) if start is None else start
    x = prob.x0
    for _ in range(n):
        x, x_prev = student.verlet_step(x, x_prev, prob, dt), x
    return x


def leapfrog(student, prob, v0, dt, n, start=None):
    x, vh = prob.x0, student.leapfrog_start(prob.x0, v0, prob, dt) if start is None else start
    for _ in range(n):
        x, vh = student.leapfrog_step(x, vh, prob, dt)
    return x


@pytest.mark.points(1)
def test_verlet_and_leapfrog_give_the_same_positions(student):
    # both start with x_1 = x_0 + h v_0 + h^2/2 a_0 and then take the same steps
    # (from the library's start-ups: a wrong start-up fails only the tests of the start-ups)
    prob = problem("chain", n=4, dim=3, stiffness=30.0, sag=0.3)
    v0 = np.random.default_rng(8).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    starts = [reference_run(m, prob, prob.x0, v0, 0.02, steps=0).memory[0] for m in ("verlet", "leapfrog")]
    xv = verlet(student, prob, v0, 0.02, 40, starts[0])
    xl = leapfrog(student, prob, v0, 0.02, 40, starts[1])
    check_array(xv, xl, rtol=1e-8, atol=1e-10, what="Verlet vs leapfrog after 40 steps")
    # ... and both are the library's Verlet (two methods that never move agree too)
    ref = reference_run("verlet", prob, prob.x0, v0, 0.02, steps=40)
    check_array(xv, ref.x, rtol=1e-8, atol=1e-10, what="Verlet after 40 steps")


@pytest.mark.points(1)
def test_starts_drawn_at_grading(student):
    # the two start-ups on a moving chain drawn at grading time (their public tests have one input)
    rng = np.random.default_rng()
    prob = problem("chain", n=int(rng.integers(3, 7)), dim=int(rng.integers(2, 4)),
                   stiffness=float(rng.uniform(20, 100)), sag=0.3)
    v0 = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    dt = float(rng.uniform(2e-3, 2e-2))
    for name in ("verlet", "leapfrog"):
        start = reference_run(name, prob, prob.x0, v0, dt, steps=0).memory[0]
        check_array(getattr(student, f"{name}_start")(prob.x0, v0, prob, dt), start, rtol=1e-10, atol=1e-12,
                    what=f"{name}_start")


@pytest.mark.points(2)
def test_verlet_is_second_order(student):
    # a spring swinging sideways, drawn at grading time: nonlinear, no closed form to imitate
    prob, v0, t_end = swinging_spring(np.random.default_rng())

    def run(n):
        dt, xs = t_end / n, []
        # from the library's start-up: this test is about the step
        x_prev, x = reference_run("verlet", prob, prob.x0, v0, dt, steps=0).memory[0], prob.x0
        for _ in range(n):
            x, x_prev = student.verlet_step(x, x_prev, prob, dt), x
            xs.append(x)
        return xs

    order = observed_order(run, prob, v0, t_end)
    assert 1.8 < order < 2.3, f"observed order {order:.2f}, expected 2"


@pytest.mark.points(1)
def test_leapfrog_stays_bounded_near_its_limit(student):
    # h w drawn in [1.6, 1.95] < 2 at grading time: stable, the amplitude stays bounded
    rng = np.random.default_rng()
    k = float(rng.uniform(0.5, 4.0))
    h = float(rng.uniform(1.6, 1.95)) / np.sqrt(k)
    prob = problem("oscillator", stiffness=k, displacement=0.2)
    x = prob.x0
    vh = reference_run("leapfrog", prob, prob.x0, prob.v0, h, steps=0).memory[0]   # the library's start:
    # this test is about the step. On the oscillator leapfrog is linear, (u, v_half) -> M (u, v_half):
    M = np.array([[1.0, h], [-k * h, 1.0 - k * h * h]])
    y, u, expected = np.array([0.2, float(vh[1, 0])]), [], []
    for _ in range(300):
        x, vh = student.leapfrog_step(x, vh, prob, h)
        y = M @ y
        u.append(float(x[1, 0]) - 1.0)
        expected.append(y[0])
    peak = max(abs(min(u)), abs(max(u)))
    assert peak < 1.0, f"amplitude grew to {peak:.3g}"
    # it oscillates (a step that never moves stays "bounded" too) and does not damp
    assert min(u) < -0.15 and max(u) > 0.15, f"u stays in [{min(u):.3g}, {max(u):.3g}]: no oscillation"
    assert max(abs(w) for w in u[-50:]) > 0.15, "the amplitude shrank (leapfrog does not damp)"
    check_array(np.array(u), np.array(expected), rtol=1e-8, atol=1e-10, what="u over 300 steps")


@pytest.mark.points(1)
def test_both_on_a_chain_drawn_at_grading(student):
    # fresh inputs every grading: no table of answers can pass
    rng = np.random.default_rng()
    prob = problem("chain", n=int(rng.integers(3, 7)), dim=int(rng.integers(2, 4)),
                   stiffness=float(rng.uniform(20, 100)), sag=0.3)
    v0 = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    dt, n = float(rng.uniform(2e-3, 1e-2)), int(rng.integers(3, 8))
    # the steps from the library's start-ups (the start-ups have tests of their own)
    for name, run in (("verlet", verlet), ("leapfrog", leapfrog)):
        start = reference_run(name, prob, prob.x0, v0, dt, steps=0).memory[0]
        ref = reference_run(name, prob, prob.x0, v0, dt, steps=n)
        check_array(run(student, prob, v0, dt, n, start), ref.x, rtol=1e-9, atol=1e-11, what=f"{name} x")
