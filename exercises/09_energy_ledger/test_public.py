"""Public tests of exercise 09 (run them: ``pytest exercises/09_energy_ledger``)."""

import numpy as np
import pytest

from mslab.grading.checks import as_numbers, check_known, check_scalar
from mslab.grading.problems import problem
from mslab.integrators import get_method
from mslab.state import State

MODULE = "energy_ledger"


def energies_by_hand(prob, x, v):
    """K and U written out particle by particle and spring by spring."""
    K = sum(0.5 * prob.mass[i] * float(v[i] @ v[i]) for i in range(len(x)) if not prob.pinned[i])
    U = 0.0
    for (i, j), k, rest in zip(prob.springs, prob.stiffness, prob.rest_length, strict=True):
        U += 0.5 * k * (np.linalg.norm(x[i] - x[j]) - rest) ** 2
    for i in range(len(x)):
        U -= prob.mass[i] * float(prob.gravity @ x[i])
    return K, U


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


@pytest.mark.points(2)
def test_kinetic_and_potential_energy_of_a_moving_chain(student):
    prob = problem("chain", n=5, dim=2, stiffness=40.0, sag=0.2)
    rng = np.random.default_rng(5)
    x = prob.x0 + 0.03 * rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    v = rng.normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    K, U = energies_by_hand(prob, x, v)
    gravity = -sum(prob.mass[i] * float(prob.gravity @ x[i]) for i in range(len(x)))
    check_scalar(student.kinetic_energy(v, prob), K, rtol=1e-10, what="K", mistakes={
        "the mass is missing: K = sum m_i |v_i|^2 / 2": 0.5 * float(np.sum(v**2)),
        "the 1/2 is missing: K = sum m_i |v_i|^2 / 2": 2.0 * K})
    check_scalar(student.potential_energy(x, prob), U, rtol=1e-10, atol=1e-12, what="U", mistakes={
        "the sign of gravity's energy: it is -m g . x (lower is less energy)": U - 2.0 * gravity,
        "gravity's energy is missing: U = springs - sum m_i g . x_i": U - gravity})


@pytest.mark.points(2)
def test_the_ledger_of_a_damped_chain_balances_along_rk4(student):
    # RK4 at a small step is nearly exact: K + U + D must stay constant
    # (to the O(dt^2) of the trapezoidal booking)
    prob = problem("chain", n=4, dim=2, stiffness=30.0, gamma=0.5, sag=0.1)
    v0 = np.random.default_rng(2).normal(size=prob.x0.shape) * (~prob.pinned)[:, None]
    dt = 1e-3
    xs, vs = library_run(prob, "rk4", v0, dt, 800)
    out = student.ledger(xs, vs, prob, dt)
    assert isinstance(out, tuple | list) and len(out) == 3, "return (K, U, D)"
    K, U, D = (as_numbers(a, what=name) for a, name in zip(out, "KUD", strict=True))
    for name, a in (("K", K), ("U", U), ("D", D)):
        assert a.shape == (801,), f"{name}: shape {a.shape}, expected (801,)"
    P = prob.gamma * np.sum(vs[:, ~prob.pinned] ** 2, axis=(1, 2))
    D_ref = np.concatenate([[0.0], np.cumsum(0.5 * dt * (P[:-1] + P[1:]))])
    rectangles = np.concatenate([[0.0], np.cumsum(dt * P[:-1])])
    check_known((D,), (D_ref,), {"the drag work by rectangles: book it by the trapezoid rule, "
                                 "dt/2 (P_n + P_n+1)": (rectangles,)}, whats=("D",), rtol=1e-9, atol=1e-12)
    assert D[-1] > 0.2 * K[0], f"the drag removed only D = {D[-1]:.3g} J of K(0) = {K[0]:.3g} J"
    total = K + U + D
    drift = np.max(np.abs(total - total[0])) / np.max(K)
    assert drift < 1e-4, f"K + U + D moved by {drift:.2e} of the kinetic energy scale"


@pytest.mark.points(2)
def test_band_and_drift_of_a_synthetic_error(student):
    # a start-up transient in the first half, then a steady loss with an oscillation on top
    t = np.linspace(0.0, 10.0, 1001)
    e = -(0.3 * np.exp(-3.0 * t) + 0.02 * np.sin(5.0 * t) + 0.003 * t)
    half = t >= 5.0
    band, rate = student.band_and_drift(t, e)
    check_scalar(band, float(np.max(np.abs(e))), rtol=1e-12, what="band", mistakes={
        "the band is the largest |error|, not the largest error": float(np.max(e))})
    check_scalar(rate, float(np.polyfit(t[half], e[half], 1)[0]), rtol=1e-8, what="drift rate", mistakes={
        "fitted over the whole run: the drift rate is the slope over the second half only":
            float(np.polyfit(t, e, 1)[0])})
