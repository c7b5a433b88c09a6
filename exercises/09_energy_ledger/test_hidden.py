"""Hidden tests of exercise 09 (graded, not released)."""

import numpy as np
import pytest

from mslab.grading.checks import as_numbers, check_scalar
from mslab.grading.problems import problem
from mslab.integrators import get_method
from mslab.precision.drift import drift_verdict
from mslab.state import State

MODULE = "energy_ledger"


def library_run(prob, method, v0, dt, n):
    system, integrator = prob.system(), get_method(method)
    state = integrator.start(system, State(prob.x0.copy(), np.array(v0, dtype=float)), dt)
    xs, vs = [state.x], [state.v]
    for _ in range(n):
        state = integrator.step(system, state, dt)
        xs.append(state.x)
        vs.append(state.v)
    return np.array(xs), np.array(vs)


def relative_error(prob, xs, vs):
    """(E - E(0)) / max K with the library's energies (the verdict test grades the rule only)."""
    system = prob.system()
    K = np.array([system.kinetic_energy(v) for v in vs])
    U = np.array([system.potential_energy(x) for x in xs])
    return (K + U - K[0] - U[0]) / np.max(K)


@pytest.mark.points(2)
def test_verdicts_of_real_runs_match_the_library(student):
    prob = problem("oscillator", stiffness=1.0, displacement=0.3)
    # (method, step, steps, verdict): implicit Euler at a small step, where its loss is steady
    expected = [("leapfrog", 0.3, 600, "bounded"), ("rk4", 0.3, 600, "drifting"),
                ("implicit_euler", 0.08, 100, "drifting")]
    for method, dt, n, label in expected:
        xs, vs = library_run(prob, method, prob.v0, dt, n)
        t = dt * np.arange(len(xs))
        e = relative_error(prob, xs, vs)
        ref = drift_verdict(t, e)["verdict"]
        assert ref == label, f"library: {method} {ref}"        # the test's own premise
        got = student.verdict(t, e)
        assert got == ref, f"{method}: verdict {got!r}, expected {ref!r}"


@pytest.mark.points(1)
def test_leapfrog_band_shrinks_four_times_when_h_halves(student):
    prob = problem("oscillator", stiffness=1.0, displacement=0.3)
    bands = []
    for dt in (0.2, 0.1):
        xs, vs = library_run(prob, "leapfrog", prob.v0, dt, round(60.0 / dt))
        out = student.ledger(xs, vs, prob, dt)                               # your energies
        assert isinstance(out, tuple | list) and len(out) == 3, "return (K, U, D)"
        K, U, D = (as_numbers(a, what=name) for a, name in zip(out, "KUD", strict=True))
        error = (K + U + D - K[0] - U[0] - D[0]) / np.max(K)
        bands.append(student.band_and_drift(dt * np.arange(len(xs)), error)[0])
    ratio = bands[0] / bands[1]
    assert 3.0 < ratio < 5.0, f"band ratio {ratio:.2f}, expected about 4"


@pytest.mark.points(1)
def test_the_trend_is_fitted_on_the_second_half_only(student):
    # a jump in the first half, a flat noisy band after it: bounded by the rule, drifting by a whole-run fit
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 20.0, 2001)
    e = np.where(t < 4.0, 0.05 * t, 0.2) + 0.01 * np.sin(7.0 * t) + 1e-3 * rng.normal(size=t.size)
    ref = drift_verdict(t, e)["verdict"]
    assert ref == "bounded"
    assert student.verdict(t, e) == ref, "verdict: expected 'bounded' (the trend of the second half is flat)"
    e2 = e + 0.01 * np.maximum(t - 10.0, 0.0)          # the same with a drift in the second half
    assert drift_verdict(t, e2)["verdict"] == "drifting"
    assert student.verdict(t, e2) == "drifting", "verdict: expected 'drifting'"


@pytest.mark.points(2)
def test_chain_and_error_drawn_at_grading(student):
    rng = np.random.default_rng()
    prob = problem("chain", n=int(rng.integers(3, 7)), dim=int(rng.integers(2, 4)),
                   stiffness=float(rng.uniform(20, 200)), sag=float(rng.uniform(0.0, 0.3)))
    free = (~prob.pinned)[:, None]
    x = prob.x0 + 0.05 * rng.normal(size=prob.x0.shape) * free
    v = rng.normal(size=prob.x0.shape) * free
    K = 0.5 * np.sum(prob.mass[:, None] * v**2)
    d = x[prob.springs[:, 0]] - x[prob.springs[:, 1]]
    U = (0.5 * np.sum(prob.stiffness * (np.linalg.norm(d, axis=1) - prob.rest_length) ** 2)
         - np.sum(prob.mass[:, None] * prob.gravity * x))
    check_scalar(student.kinetic_energy(v, prob), float(K), rtol=1e-10, what="K")
    check_scalar(student.potential_energy(x, prob), float(U), rtol=1e-10, atol=1e-12, what="U")
    t = np.linspace(0.0, float(rng.uniform(5, 50)), int(rng.integers(200, 2000)))
    e = (rng.uniform(0.001, 0.05) * np.sin(rng.uniform(1, 10) * t) + rng.uniform(-0.01, 0.01) * t
         + 1e-3 * rng.normal(size=t.size))
    half = t >= t[0] + 0.5 * (t[-1] - t[0])
    band, rate = student.band_and_drift(t, e)
    check_scalar(band, float(np.max(np.abs(e))), rtol=1e-12, what="band")
    check_scalar(rate, float(np.polyfit(t[half], e[half], 1)[0]), rtol=1e-8, atol=1e-12, what="drift rate")
    assert student.verdict(t, e) == drift_verdict(t, e)["verdict"], "verdict differs from the rule"
