"""The first edge of a stability interval with a narrow unstable gap (issue 41): yoshida6 on a damped mode.

On a mode with damping ratio sin(0.04), yoshida6 is unstable for dt w in about [2.2962, 2.3022]
and stable again up to 2.8189; the ray scan's grid (1.5 % apart) stepped over the gap and
predicted 2.8189, so a run inside the gap counted as within the stable dt (no warning, no
ledger verdict) and finished with its energy grown 40-fold. The prediction is now the first
root of rho = 1 on the ray: the gap's lower edge.
"""

import dataclasses
import warnings

import numpy as np
import pytest

import mslab
from mslab import stability as st

ZETA = np.sin(0.04)


def damped_oscillator():
    """Unit mass, unit spring (w0 = 1), drag 2 zeta: eigenvalues -zeta +- i sqrt(1 - zeta^2), |lam| = 1."""
    b = mslab.SceneBuilder(1)
    anchor = b.add_particle([-1.0], pinned=True)
    p = b.add_particle([0.0], mass=1.0)
    b.add_spring(anchor, p, 1.0, rest_length=1.0)
    b.add_damping(2 * ZETA)
    sc = b.build()
    x = sc.state0.x.copy()
    x[p, 0] = 0.3
    return dataclasses.replace(sc, state0=mslab.State(x, sc.state0.v))


def _edges(method, lo, hi, n=700_001):
    """Where the spectral radius of the oscillator map crosses 1 on a fine grid of dt w (brute force)."""
    hw = np.linspace(lo, hi, n)
    rho = st.spectral_radius(st.amplification_matrix(method, hw, 2 * ZETA * hw))
    return hw[np.flatnonzero(np.diff((rho > 1 + 1e-10).astype(int)))]


def test_the_prediction_is_the_gaps_lower_edge():
    edges = _edges("yoshida6", 2.2, 2.9)
    assert edges.size == 3 and edges[1] - edges[0] < 0.01  # a gap narrower than the scan's grid
    assert edges[2] > 2.8
    measured = st.measured_amplification_matrix("yoshida6", 0.5 * (edges[0] + edges[1]), 2 * ZETA * 0.5 * (
        edges[0] + edges[1]))  # the real integrator's steps: unstable inside the gap
    assert np.max(np.abs(np.linalg.eigvals(measured))) > 1.0
    sc = damped_oscillator()
    assert np.abs(st.eigenvalues(sc)).max() == pytest.approx(1.0, rel=1e-12)
    assert st.max_stable_dt(sc, "yoshida6") == pytest.approx(edges[0], abs=2e-6)  # was 2.8189


def _run(sc, dt, steps=4000):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            tr = mslab.simulate(sc, "yoshida6", dt=dt, t_end=steps * dt, save_every=20)
        except mslab.InstabilityError as e:
            return e, caught
    return tr, caught


def test_a_run_inside_the_gap_is_predicted_unstable_and_stopped():
    sc = damped_oscillator()
    edges = _edges("yoshida6", 2.2, 2.9)
    outcome, caught = _run(sc, 0.5 * (edges[0] + edges[1]))
    assert any(issubclass(w.category, mslab.StabilityWarning) for w in caught)  # the pre-check warns
    assert isinstance(outcome, mslab.InstabilityError)  # was completed, energy x 40
    assert "unstable at this dt" in str(outcome) and "predicted stable dt = 2.296" in str(outcome)
    below, caught = _run(sc, 0.995 * edges[0])  # just below the gap: stable, no warning, completes
    assert below.complete and not caught
    above, caught = _run(sc, 0.5 * (edges[1] + edges[2]))  # the second stable interval: beyond the first edge
    assert any(issubclass(w.category, mslab.StabilityWarning) for w in caught)
    assert above.complete  # bounded energy: nothing stops it
