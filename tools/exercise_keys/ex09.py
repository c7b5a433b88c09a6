"""Key of exercise 09 (the energy ledger): the energies, the drag work, the band and the drift rate.

The right answers and the known mistakes' answers of the public tests, written out by hand.
"""

import numpy as np


def _energies(prob, x, v):
    """K and U written out particle by particle and spring by spring, and gravity's part of U."""
    K = sum(0.5 * prob.mass[i] * float(v[i] @ v[i]) for i in range(len(x)) if not prob.pinned[i])
    springs = 0.0
    for (i, j), k, rest in zip(prob.springs, prob.stiffness, prob.rest_length, strict=True):
        springs += 0.5 * k * (np.linalg.norm(x[i] - x[j]) - rest) ** 2
    gravity = -sum(prob.mass[i] * float(prob.gravity @ x[i]) for i in range(len(x)))
    return K, springs + gravity, gravity


def _kinetic(t):
    prob, x, v = t.moving_chain()
    K, _, _ = _energies(prob, x, v)
    return {"expected": [K], "mistakes": {
        "the mass is missing: K = sum m_i |v_i|^2 / 2": [0.5 * float(np.sum(v**2))],
        "the 1/2 is missing: K = sum m_i |v_i|^2 / 2": [2.0 * K]}}


def _potential(t):
    prob, x, v = t.moving_chain()
    _, U, gravity = _energies(prob, x, v)
    return {"expected": [U], "mistakes": {
        "the sign of gravity's energy: it is -m g . x (lower is less energy)": [U - 2.0 * gravity],
        "gravity's energy is missing: U = springs - sum m_i g . x_i": [U - gravity]}}


def _drag_work(t):
    prob, dt, _, vs = t.damped_chain_run()
    P = prob.gamma * np.sum(vs[:, ~prob.pinned] ** 2, axis=(1, 2))
    return {"expected": [np.concatenate([[0.0], np.cumsum(0.5 * dt * (P[:-1] + P[1:]))])], "mistakes": {
        "the drag work by rectangles: book it by the trapezoid rule, dt/2 (P_n + P_n+1)":
        [np.concatenate([[0.0], np.cumsum(dt * P[:-1])])]}}


def _band(t):
    _, e = t.synthetic_error()
    return {"expected": [float(np.max(np.abs(e)))],
            "mistakes": {"the band is the largest |error|, not the largest error": [float(np.max(e))]}}


def _drift_rate(t):
    time, e = t.synthetic_error()
    half = time >= 5.0
    return {"expected": [float(np.polyfit(time[half], e[half], 1)[0])], "mistakes": {
        "fitted over the whole run: the drift rate is the slope over the second half only":
        [float(np.polyfit(time, e, 1)[0])]}}


CASES = {"kinetic_energy": _kinetic, "potential_energy": _potential, "damped_chain_drag_work": _drag_work,
         "synthetic_band": _band, "synthetic_drift_rate": _drift_rate}
