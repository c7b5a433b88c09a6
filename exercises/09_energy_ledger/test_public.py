"""Public tests of exercise 09 (run them from the folder above: ``pytest 09_energy_ledger``)."""

import numpy as np
import pytest

from mslab.grading.checks import as_numbers, check_known, check_scalar
from mslab.grading.expected import Expected
from mslab.grading.problems import problem
from mslab.integrators import get_method
from mslab.state import State

MODULE = "energy_ledger"
EXPECTED = Expected(__file__)  # the right answers and the known mistakes' answers, as numbers (expected.json)


def library_run(prob, method, v0, dt, n):
    """Positions and velocities of mslab's ``method`` at every step: shape (n + 1, n_particles, dim)."""
    system, integrator = prob.system(), get_method(method)
    state = integrator.start(system, State(prob.x0.copy(), np.array(v0, dtype=float)), dt)
    xs, vs = [state.x], [state.v]
    for _ in range(n):
        state = integrator.step(system, state, dt)
        xs.append(state.x)
        vs.append(state.v)
    return np.array(xs), np.array(vs)


def moving_chain():
    """A sagging chain, its free particles moved and given random velocities: (problem, x, v)."""
    prob = problem("chain", n=5, dim=2, stiffness=40.0, sag=0.2)
    rng = np.random.default_rng(5)
    x = prob.x0 + 0.03 * rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    v = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    return prob, x, v


def damped_chain_run():
    """A damped chain run by mslab's RK4 for 800 steps: (problem, dt, xs, vs)."""
    prob = problem("chain", n=4, dim=2, stiffness=30.0, gamma=0.5, sag=0.1)
    v0 = np.random.default_rng(2).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    dt = 1e-3
    return (prob, dt, *library_run(prob, "rk4", v0, dt, 800))


def synthetic_error():
    # a start-up transient in the first half, then a steady loss with an oscillation on top
    t = np.linspace(0.0, 10.0, 1001)
    return t, -(0.3 * np.exp(-3.0 * t) + 0.02 * np.sin(5.0 * t) + 0.003 * t)


@pytest.mark.points(2)
def test_kinetic_and_potential_energy_of_a_moving_chain(student):
    prob, x, v = moving_chain()
    K, wrong_K = EXPECTED.scalar("kinetic_energy")
    U, wrong_U = EXPECTED.scalar("potential_energy")
    check_scalar(student.kinetic_energy(v, prob), K, rtol=1e-10, what="K", mistakes=wrong_K)
    check_scalar(student.potential_energy(x, prob), U, rtol=1e-10, atol=1e-12, what="U", mistakes=wrong_U)


@pytest.mark.points(2)
def test_the_ledger_of_a_damped_chain_balances_along_rk4(student):
    # RK4 at a small step is nearly exact: K + U + D must stay constant
    # (to the O(dt^2) of the trapezoidal booking)
    prob, dt, xs, vs = damped_chain_run()
    out = student.ledger(xs, vs, prob, dt)
    assert isinstance(out, tuple | list) and len(out) == 3, "return (K, U, D)"
    K, U, D = (as_numbers(a, what=name) for a, name in zip(out, "KUD", strict=True))
    for name, a in (("K", K), ("U", U), ("D", D)):
        assert a.shape == (801,), f"{name}: shape {a.shape}, expected (801,)"
    D_ref, wrong = EXPECTED.arrays("damped_chain_drag_work")
    check_known((D,), D_ref, wrong, whats=("D",), rtol=1e-9, atol=1e-12)
    assert D[-1] > 0.2 * K[0], f"the drag removed only D = {D[-1]:.3g} J of K(0) = {K[0]:.3g} J"
    total = K + U + D
    drift = np.max(np.abs(total - total[0])) / np.max(K)
    assert drift < 1e-4, f"K + U + D moved by {drift:.2e} of the kinetic energy scale"


@pytest.mark.points(2)
def test_band_and_drift_of_a_synthetic_error(student):
    band, rate = student.band_and_drift(*synthetic_error())
    expected_band, wrong_band = EXPECTED.scalar("synthetic_band")
    expected_rate, wrong_rate = EXPECTED.scalar("synthetic_drift_rate")
    check_scalar(band, expected_band, rtol=1e-12, what="band", mistakes=wrong_band)
    check_scalar(rate, expected_rate, rtol=1e-8, what="drift rate", mistakes=wrong_rate)
