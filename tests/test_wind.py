"""The wind effect against closed-form truth: motion, dissipated and external work, the ledger balance."""

from __future__ import annotations

import json

import numpy as np
import pytest

import mslab
from mslab.errors import SceneError
from mslab.trajectory import Energy

M, C = 2.0, 0.8  # mass (kg) and drag (kg/s): relaxation time m / c = 2.5 s


def particle_in_wind(dim: int, v0, w, mass: float = M, drag: float = C):
    b = mslab.SceneBuilder(dim)
    b.add_particle(np.linspace(0.1, 0.3, dim), mass=mass, velocity=v0)
    b.add_wind(velocity=w, drag=drag)
    return b.build()


def exact(t, x0, v0, w, mass: float = M, drag: float = C):
    """Closed form of m v' = -c (v - w): velocity, position, dissipated work c int |v|^2, wind work."""
    t, x0, v0, w = (np.asarray(a, dtype=float) for a in (t, x0, v0, w))
    k = drag / mass
    e1, e2 = np.exp(-k * t), np.exp(-2 * k * t)
    u = v0 - w
    v = w + u * e1[:, None]
    x = x0 + w * t[:, None] + u * ((1 - e1) / k)[:, None]
    dissipated = drag * (w @ w * t + 2 * (w @ u) * (1 - e1) / k + u @ u * (1 - e2) / (2 * k))
    external = drag * (w @ w * t + (w @ u) * (1 - e1) / k)  # c w . (x - x0)
    return x, v, dissipated, external


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("dim", [2, 3])
def test_particle_relaxes_to_the_wind(dim, backend):
    """v(t) = w + (v0 - w) exp(-c t / m); x, D and W_ext closed form too; K + U + D - W_ext constant."""
    v0, w = [0.5, 1.0, -0.3][:dim], [3.0, -1.0, 0.7][:dim]
    scene = particle_in_wind(dim, v0, w)
    tr = mslab.simulate(scene, "rk4", dt=1e-3, t_end=4.0, save_every=250, backend=backend)
    x, v, dissipated, external = exact(tr.t, scene.state0.x[0], v0, w)
    np.testing.assert_allclose(tr.v[:, 0], v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.x[:, 0], x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.energy.dissipated, dissipated, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tr.energy.external, external, rtol=1e-12, atol=1e-12)
    kinetic = 0.5 * M * np.sum(v * v, axis=1)
    np.testing.assert_allclose(tr.energy.kinetic, kinetic, rtol=1e-12)
    # the balance: K + D = K(0) + W_ext (no potential energy here), and the wind did put energy in
    assert external[-1] > kinetic[-1] - kinetic[0] > 0
    assert np.max(np.abs(tr.energy.total - tr.energy.total[0])) < 1e-11 * external[-1]
    assert tr.energy.relative_drift()[-1] == pytest.approx(0.0, abs=1e-11)


def test_wind_against_the_motion_takes_energy_out():
    """A particle flying into a head wind: W_ext < 0 (the wind works against it), still balanced."""
    scene = particle_in_wind(2, [4.0, 0.0], [-1.0, 0.0])
    tr = mslab.simulate(scene, "rk4", dt=1e-3, t_end=1.0, save_every=100)
    _, _, dissipated, external = exact(tr.t, scene.state0.x[0], [4.0, 0.0], [-1.0, 0.0])
    assert external[-1] < 0 and tr.energy.external[-1] == pytest.approx(external[-1], rel=1e-12)
    assert tr.energy.dissipated[-1] == pytest.approx(dissipated[-1], rel=1e-12)
    assert np.ptp(tr.energy.total) < 1e-12 * tr.energy.kinetic[0]


#: symplectic Runge-Kutta methods conserve quadratic invariants: their ledger closes to round-off
QUADRATIC = [m for m in mslab.methods()
             if mslab.get_method(m).family == "implicit_rk" and mslab.get_method(m).symplectic]


def driven_oscillator():
    """Wind, gravity and an anchor spring on one particle, and its closed-form motion x(t).

    ``m x'' = -c (x' - w) - k x + m g``: a damped oscillator about ``x* = (c w + m g) / k``.
    """
    k, w, g = 5.0, np.array([2.0, 0.5]), np.array([0.0, -9.81])
    b = mslab.SceneBuilder(2)
    b.add_particle([0.4, 0.0], mass=M, velocity=[0.0, 1.0])
    b.add_wind(velocity=w, drag=C)
    b.add_anchors([0], stiffness=k, points=[[0.0, 0.0]])
    b.add_gravity(g)
    scene = b.build()
    rest = (C * w + M * g) / k
    lam = np.roots([M, C, k])  # a complex pair
    y0, yd0 = scene.state0.x[0] - rest, scene.state0.v[0]
    coef = np.linalg.solve(np.array([[1, 1], lam]), np.vstack([y0, yd0]))  # y = a e^{l1 t} + b e^{l2 t}

    def exact_x(t):
        y = coef[0][None] * np.exp(lam[0] * t)[:, None] + coef[1][None] * np.exp(lam[1] * t)[:, None]
        return rest + y.real

    return scene, exact_x


@pytest.mark.parametrize("method", mslab.methods())
def test_every_method_converges_and_balances_the_ledger_in_wind(method):
    """Errors against the closed form fall as dt^p; the ledger K + U + D - W_ext drifts at order >= p.

    Implicit methods use the wind's Jacobian ``df/dv = -c I``; symplectic Runge-Kutta methods
    keep the ledger of this linear system to round-off (a quadratic invariant).
    """
    scene, exact_x = driven_oscillator()
    order = mslab.get_method(method).order
    # high orders reach round-off at small steps: fit them where the error is still visible
    dts = (0.01, 0.005, 0.0025) if order <= 2 else (0.04, 0.02, 0.01) if order <= 4 else (0.1, 0.05, 0.025)
    errors, drifts = [], []
    for dt in dts:
        tr = mslab.simulate(scene, method, dt=dt, t_end=2.0, check_stability=False)
        errors.append(np.max(np.abs(tr.x[:, 0] - exact_x(tr.t))))
        drifts.append(np.max(np.abs(tr.energy.total - tr.energy.total[0])))
        assert abs(tr.energy.external[-1]) > 1.0 and tr.energy.dissipated[-1] > 1.0  # both columns matter
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert slope == pytest.approx(order, abs=0.3), (method, errors)
    if method in QUADRATIC:
        assert max(drifts) < 1e-12, drifts
    else:  # at least the method's order (Heun: 3 on a linear problem); a wrong W_ext would stay O(1)
        slope = np.polyfit(np.log(dts), np.log(drifts), 1)[0]
        assert order - 0.25 < slope < order + 1.25, (method, drifts)


def test_implicit_newton_step_uses_the_wind_jacobian():
    """Implicit Euler on the linear wind ODE is exact after one Newton iteration per step."""
    scene = particle_in_wind(2, [0.0, 0.0], [1.0, 2.0])
    tr = mslab.simulate(scene, "implicit_euler", dt=0.1, t_end=1.0)
    # backward Euler on v' = -k (v - w): v_{n+1} - w = (v_n - w) / (1 + k dt)
    k = C / M
    v = np.array([1.0, 2.0]) * (1 - (1 + 0.1 * k) ** -10.0)
    np.testing.assert_allclose(tr.v[-1, 0], v, rtol=1e-12)
    assert tr.stats.n_jac >= 1


def test_energy_keeps_three_columns_for_old_code():
    """``Energy(K, U, D)`` still builds a ledger: external work defaults to zeros."""
    e = Energy(np.array([1.0, 2.0]), np.array([3.0, 1.0]), np.array([0.0, 1.0]))
    assert np.array_equal(e.external, [0.0, 0.0]) and np.array_equal(e.total, [4.0, 4.0])
    e = Energy(np.array([1.0, 2.0]), np.array([3.0, 1.0]), np.array([0.0, 1.0]), np.array([0.0, 0.5]))
    assert np.array_equal(e.total, [4.0, 3.5])


def test_scenes_without_wind_have_a_zero_external_column():
    tr = mslab.simulate(mslab.load_scene("hanging_rope"), t_end=0.1)
    assert tr.energy.external.shape == tr.t.shape and not np.any(tr.energy.external)


WIND_TOML = """
[scene]
name = "kite"
dim = 2

[particles]
positions = [[0.0, 0.0], [1.0, 0.0]]
mass = 0.5
pinned = [0]

[springs.structural]
pairs = [[0, 1]]
stiffness = 50.0

[wind]
velocity = [4.0, 1.0]
drag = 0.3

[run]
method = "rk4"
dt = 0.001
t_end = 0.5
"""


def test_wind_section_in_a_scene_file(tmp_path):
    path = tmp_path / "kite.toml"
    path.write_text(WIND_TOML)
    scene = mslab.load_scene(path)
    assert scene.effects == ["springs", "wind"]
    wind = scene.system.effects[1]
    assert wind.drag == 0.3 and wind.velocity.tolist() == [4.0, 1.0]
    path.write_text(WIND_TOML.replace("velocity = [4.0, 1.0]", "velocity = [4.0, 1.0, 2.0]"))
    with pytest.raises(SceneError, match=r"kite.toml: wind.velocity: must be a list of 2 numbers"):
        mslab.load_scene(path)
    path.write_text(WIND_TOML.replace("drag = 0.3", "drag = -0.3"))
    with pytest.raises(SceneError, match=r"wind.drag"):
        mslab.load_scene(path)
    path.write_text(WIND_TOML.replace("drag = 0.3", "drag = 0.0"))
    assert mslab.load_scene(path).effects == ["springs"]  # no drag: nothing built


def test_mslab_run_reports_the_external_work(tmp_path, capsys):
    from mslab.cli import main

    path = tmp_path / "kite.toml"
    path.write_text(WIND_TOML)
    assert main(["run", str(path), "--json"]) in (0, None)
    doc = json.loads(capsys.readouterr().out)
    energy = doc["energy"]
    assert energy["final_external"] > 0.0
    assert abs(energy["relative_drift"]) < 1e-8  # K + U + D - W_ext balanced (rk4, dt = 1e-3)
    assert main(["run", str(path)]) in (0, None)
    assert "K + U + D - W_ext" in capsys.readouterr().out
