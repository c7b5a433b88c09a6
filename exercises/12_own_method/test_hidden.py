"""Hidden tests of exercise 12 (graded, not released)."""

import numpy as np
import pytest

from mslab import ExplicitRK
from mslab.derive import order
from mslab.grading.checks import as_numbers, check_array, fitted_order, step_order
from mslab.grading.problems import problem
from mslab.integrators import get_method
from mslab.scenes.generators import oscillator_solution
from mslab.state import State

MODULE = "own_method"


def tableau(out):
    assert isinstance(out, tuple | list) and len(out) == 2, "return (A, b)"
    A, b = as_numbers(out[0], (3, 3), what="A"), as_numbers(out[1], (3,), what="b")
    assert np.all(np.triu(A) == 0.0), "A must be strictly lower triangular (an explicit method)"
    return A, b


@pytest.mark.points(1)
def test_kutta_family_at_nodes_drawn_at_grading(student):
    rng = np.random.default_rng()
    for _ in range(3):
        c2 = float(rng.uniform(0.1, 0.55))          # away from 2/3, 0 and c3
        c3 = float(rng.uniform(0.7, 1.2))
        A, b = tableau(student.kutta_family(c2, c3))
        check_array(A.sum(axis=1), [0.0, c2, c3], rtol=1e-10, atol=1e-12, what="nodes c = A 1")
        c = A.sum(axis=1)
        residuals = [b.sum() - 1, b @ c - 1 / 2, b @ c**2 - 1 / 3, b @ A @ c - 1 / 6]
        assert np.max(np.abs(residuals)) < 1e-10, f"order conditions not met at c2 = {c2:.3f}, c3 = {c3:.3f}"
        assert order(ExplicitRK(A, b, name="drawn")) == 3


@pytest.mark.points(1)
def test_my_method_has_order_three_in_the_library(student):
    # your tableau stepped by the library (your rk3_step has a test of its own)
    A, b = tableau(student.my_method())
    prob = problem("oscillator", stiffness=4.0, displacement=0.3)
    t_end = 2.0
    u, _ = oscillator_solution(2.0, 0.3, t_end, 0.0)
    method, system = ExplicitRK(A, b, name="student"), prob.system()
    dts = [0.1, 0.05, 0.025, 0.0125]
    errors = []
    for dt in dts:
        state = State(prob.x0.copy(), prob.v0.copy())
        for _ in range(round(t_end / dt)):
            state = method.step(system, state, dt)
        errors.append(abs(float(state.x[1, 0]) - 1.0 - float(u)))
    p = fitted_order(dts, errors)
    assert 2.7 < p < 3.3, f"measured order {p:.2f}, expected 3"


@pytest.mark.points(1)
def test_rk3_step_converges_with_order_three(student):
    # Kutta's third-order tableau (the library's rk3) in your steps, on a spring swinging sideways
    # drawn at grading time (nonlinear, no closed form to imitate)
    rk3 = get_method("rk3")
    A, b = np.array(rk3.A, dtype=float), np.array(rk3.b, dtype=float)
    order = step_order(student.rk3_step, np.random.default_rng(), A, b)
    assert 2.7 < order < 3.4, f"observed order {order:.2f}, expected 3"
    # one step of a drawn three-stage tableau on a moving chain against the library's stepping
    rng = np.random.default_rng()
    A, b = np.tril(rng.uniform(-1, 1, (3, 3)), k=-1), rng.uniform(0, 1, 3)
    chain = problem("chain", n=4, dim=2, stiffness=50.0, gamma=0.3, sag=0.2)
    v0 = rng.normal(size=chain.x0.shape) * (~chain.pinned)[:, None]
    ref = ExplicitRK(A, b, name="drawn").step(chain.system(), State(chain.x0.copy(), v0.copy()), 0.01)
    x1, v1 = student.rk3_step(chain.x0, v0, chain, 0.01, A, b)
    check_array(x1, ref.x, rtol=1e-10, atol=1e-12, what="x after one step")
    check_array(v1, ref.v, rtol=1e-10, atol=1e-12, what="v after one step")


@pytest.mark.points(1)
def test_my_method_has_the_third_order_stability_function(student):
    # every three-stage method of order 3: R(z) = 1 + z + z^2/2 + z^3/6 (lesson 10)
    A, b = tableau(student.my_method())
    z = np.array([-2.5, 1.5j, -1.0 + 1.0j])
    stages = []
    for i in range(3):
        stages.append(1.0 + z * sum(A[i, j] * stages[j] for j in range(i)))
    R = 1.0 + z * sum(b[i] * stages[i] for i in range(3))
    check_array(R, 1 + z + z**2 / 2 + z**3 / 6, rtol=1e-10, atol=1e-12, what="R(z)")
