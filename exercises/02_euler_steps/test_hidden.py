"""Hidden tests of exercise 02 (graded, not released)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, reference_run
from mslab.grading.problems import problem

MODULE = "euler_steps"


def energy(prob, x, v):
    u = np.linalg.norm(x[1] - x[0]) - prob.rest_length[0]
    return 0.5 * prob.stiffness[0] * u * u + 0.5 * prob.mass[1] * float(v[1] @ v[1])


def run(step, prob, dt, n):
    x, v = prob.x0, prob.v0
    energies = [energy(prob, x, v)]
    for _ in range(n):
        x, v = step(x, v, prob, dt)
        energies.append(energy(prob, x, v))
    return x, v, np.array(energies)


@pytest.mark.points(2)
def test_forward_euler_with_drag_matches_the_library(student):
    prob = problem("chain", n=5, dim=3, stiffness=80.0, gamma=0.5, sag=0.3)
    rng = np.random.default_rng(5)
    v0 = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    ref = reference_run("euler", prob, prob.x0, v0, 0.005)
    x, v = student.forward_euler_step(prob.x0, v0, prob, 0.005)
    check_array(x, ref.x, what="x_new")
    check_array(v, ref.v, what="v_new")


@pytest.mark.points(2)
def test_forward_euler_gains_energy_every_step(student):
    # |R(i w h)| = sqrt(1 + (w h)^2) > 1: the energy grows by exactly that factor squared, and
    # the state is forward Euler's own, (u, v) -> [[1, h], [-w^2 h, 1]] (u, v) (drawn at grading time)
    rng = np.random.default_rng()
    k, h = float(rng.uniform(0.5, 2.0)), float(rng.uniform(0.05, 0.1))  # k h^2 <= 0.02: stays linear
    prob = problem("oscillator", stiffness=k, displacement=0.2)
    x, v, e = run(student.forward_euler_step, prob, h, 50)
    check_array(e[1:] / e[:-1], np.full(50, 1.0 + k * h * h), rtol=1e-9, what="energy ratio per step")
    y = np.linalg.matrix_power(np.array([[1.0, h], [-k * h, 1.0]]), 50) @ np.array([0.2, 0.0])
    check_array(np.array([float(x[1, 0]) - 1.0, float(v[1, 0])]), y, rtol=1e-9, atol=1e-12,
                what="(u, v) after 50 steps")


@pytest.mark.points(2)
def test_symplectic_eulers_keep_the_energy_bounded(student):
    prob = problem("oscillator", stiffness=1.0, displacement=0.2)
    for name in ("symplectic_euler_step", "symplectic_euler_x_step"):
        x, _, e = run(getattr(student, name), prob, 0.1, 400)
        assert np.all(np.isfinite(e)) and np.max(np.abs(e / e[0] - 1.0)) < 0.06, f"{name}: energy drifts"
        ref = reference_run(name.removesuffix("_step"), prob, prob.x0, prob.v0, 0.1, steps=400)
        check_array(x, ref.x, rtol=1e-8, atol=1e-10, what=f"{name}: x after 400 steps")


@pytest.mark.points(1)
def test_all_three_on_a_chain_drawn_at_grading(student):
    # fresh inputs every grading: no table of answers can pass
    rng = np.random.default_rng()
    prob = problem("chain", n=int(rng.integers(3, 7)), dim=int(rng.integers(1, 4)),
                   stiffness=float(rng.uniform(20, 200)), gamma=float(rng.uniform(0, 1)), sag=0.2)
    v0 = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    dt = float(rng.uniform(1e-3, 1e-2))
    for name in ("euler", "symplectic_euler", "symplectic_euler_x"):
        ref = reference_run(name, prob, prob.x0, v0, dt)
        step = "forward_euler_step" if name == "euler" else f"{name}_step"
        x, v = getattr(student, step)(prob.x0, v0, prob, dt)
        check_array(x, ref.x, rtol=1e-10, atol=1e-12, what=f"{step}: x_new")
        check_array(v, ref.v, rtol=1e-10, atol=1e-12, what=f"{step}: v_new")
