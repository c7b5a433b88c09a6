"""Hidden tests that only a real method passes (issue 35, item 9).

A red team's answers imitated the exact flow of the oscillator plus an error of the
tested order (forward Euler: the exact flow scaled by its energy gain; implicit Euler:
damped by its loss), implementing no method, and scored 12 of 65 points on exercises
02-06: order, energy-gain, boundedness and damping tests all ran on the oscillator, with
fixed inputs. The mimic below is that answer for every function of the five exercises; it
must score nothing.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from mslab.grading import find_exercises, grade

SOURCE = Path(__file__).resolve().parents[1] / "exercises"
TARGETS = ["02_euler_steps", "03_heun_midpoint", "04_rk4_tableau", "05_verlet_leapfrog", "06_implicit_euler"]

MIMIC = '''
import numpy as np


def _flow(x, v, prob, dt, gain=1.0, err=0.0):
    """The exact flow of the oscillator along its axis (no method), scaled, plus an error."""
    w = np.sqrt(prob.stiffness[0] / prob.mass[1])
    rest = prob.rest_length[0]
    u, s = x[1, 0] - x[0, 0] - rest, v[1, 0]
    c, sn = np.cos(w * dt), np.sin(w * dt)
    x2, v2 = np.array(x, dtype=float), np.array(v, dtype=float)
    x2[1, 0] = x[0, 0] + rest + gain * (c * u + sn * s / w) + err
    v2[1, 0] = gain * (-w * sn * u + c * s)
    return x2, v2


def _gain(prob, dt):
    return np.sqrt(1.0 + prob.stiffness[0] / prob.mass[1] * dt * dt)


def forward_euler_step(x, v, accel, dt):
    return _flow(x, v, accel, dt, gain=_gain(accel, dt))


def symplectic_euler_step(x, v, accel, dt):
    return _flow(x, v, accel, dt, err=dt ** 2)


symplectic_euler_x_step = symplectic_euler_step


def heun_step(x, v, accel, dt):
    return _flow(x, v, accel, dt, err=dt ** 3)


midpoint_step = heun_step


def rk4_tableau():
    return np.zeros((4, 4)), np.zeros(4), np.zeros(4)


def rk_step(x, v, accel, dt, A, b):
    return _flow(x, v, accel, dt, err=dt ** 5)


def verlet_start(x0, v0, accel, dt):
    return _flow(x0, v0, accel, -dt)[0]


def verlet_step(x, x_prev, accel, dt):
    w = np.sqrt(accel.stiffness[0] / accel.mass[1])
    out = np.array(x, dtype=float)
    out[1, 0] = 2.0 * np.cos(w * dt) * x[1, 0] - x_prev[1, 0] + (2.0 - 2.0 * np.cos(w * dt)) * (
        x[0, 0] + accel.rest_length[0]) + dt ** 4
    return out


def leapfrog_start(x0, v0, accel, dt):
    return np.array(v0, dtype=float)


def leapfrog_step(x, v_half, accel, dt):
    return _flow(x, v_half, accel, dt, err=dt ** 3)


def implicit_euler_newton(x, v, accel, dt, tol=1e-10, max_iter=20):
    return (*_flow(x, v, accel, dt, gain=1.0 / _gain(accel, dt)), 3)


def implicit_euler_fixed_point(x, v, accel, dt, tol=1e-10, max_iter=100):
    return implicit_euler_newton(x, v, accel, dt)
'''


@pytest.mark.slow
def test_an_imitation_of_the_exact_flow_scores_nothing(tmp_path):
    modules = {ex.name: ex.module for ex in find_exercises(SOURCE)}
    student = tmp_path / "mimic"
    for name in TARGETS:
        (student / name).mkdir(parents=True)
        (student / name / modules[name]).write_text(MIMIC)
    (result,) = grade([student], source=SOURCE, jobs=2, timeout=10.0, only=TARGETS)
    passed = {f"{ex.name}::{t.test}": t.points for ex in result.exercises for t in ex.tests if t.passed}
    assert passed == {}
    assert result.total == 0
