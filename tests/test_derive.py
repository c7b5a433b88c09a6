"""mslab.derive: orders and local errors from Taylor expansions, against hand derivations."""

import numpy as np
import pytest
import sympy as sp

import mslab
from mslab import derive
from mslab.scenes.generators import oscillator

h = sp.Symbol("h", positive=True)
f, f1, f2 = sp.symbols("f f' f''")
v, a, a1, a2 = sp.symbols("v a a' a''")
z = sp.Symbol("z")


def same(expr, expected) -> bool:
    return sp.simplify(sp.expand(expr - expected)) == 0


@pytest.mark.parametrize("name", mslab.methods())
def test_order_matches_registry(name):
    assert derive.order(name) == mslab.get_method(name).order


def test_taylor_series_of_first_order_ode():
    # y' = f, y'' = f' f, y''' = f'' f^2 + f'^2 f (chain rule by hand)
    y = sp.Symbol("y")
    expected = y + h * f + h**2 / 2 * f1 * f + h**3 / 6 * (f2 * f**2 + f1**2 * f)
    assert same(derive.taylor(3), expected)


def test_derivatives_of_second_order_ode():
    d = derive.derivatives(4, "second")
    assert d[0] == v and d[1] == a
    assert same(d[2], a1 * v)
    assert same(d[3], a2 * v**2 + a1 * a)


@pytest.mark.parametrize("name, expected", [
    ("euler", h**2 / 2 * f * f1),                                    # y''/2 h^2, seed eq. 6
    ("implicit_euler", -h**2 / 2 * f * f1),
    ("implicit_euler_fp", -h**2 / 2 * f * f1),
    # Heun: y + h/2 (f + f(y + h f)) = y + h f + h^2/2 f'f + h^3/4 f'' f^2 + ...
    ("heun", h**3 * (f**2 * f2 / 6 + f * f1**2 / 6 - f**2 * f2 / 4)),
    # midpoint: y + h f(y + h/2 f) = y + h f + h^2/2 f'f + h^3/8 f'' f^2 + ...
    ("midpoint", h**3 * (f**2 * f2 / 6 + f * f1**2 / 6 - f**2 * f2 / 8)),
])
def test_local_error_first_order(name, expected):
    assert same(derive.local_error(name), expected)


def test_local_error_symplectic_euler_variants():
    # velocity first: x1 = x + h v + h^2 a, v1 = v + h a
    ex, ev = derive.local_error("symplectic_euler")
    assert same(ex, -h**2 / 2 * a) and same(ev, h**2 / 2 * a1 * v)
    # position first: x1 = x + h v, v1 = v + h a(x + h v) = v + h a + h^2 a' v + ...
    ex, ev = derive.local_error("symplectic_euler_x")
    assert same(ex, h**2 / 2 * a) and same(ev, -h**2 / 2 * a1 * v)


@pytest.mark.parametrize("name", ["leapfrog", "velocity_verlet"])
def test_local_error_velocity_verlet_family(name):
    # x1 = x + h v + h^2/2 a misses h^3/6 x''' = h^3/6 a' v
    ex, ev = derive.local_error(name)
    assert same(ex, h**3 / 6 * a1 * v)
    # v1 = v + h/2 (a + a(x1)): trapezoidal rule, error -h^3/12 v''
    assert same(ev, -h**3 / 12 * (a2 * v**2 + a1 * a))


def test_verlet_two_step_residual():
    # seed eqs. 21-23: the odd terms cancel, h^4/12 x'''' remains
    assert same(derive.local_error("verlet"), h**4 / 12 * (a2 * v**2 + a1 * a))
    assert derive.analyse("verlet").problem.startswith("two-step")


def test_wrong_tableaux_give_lower_order():
    assert derive.order(mslab.ExplicitRK([[0, 0], [1, 0]], [1, 0])) == 1
    # Kutta's rk3 with a wrong third row: sum b c = 1/3 != 1/2
    assert derive.order(mslab.ExplicitRK([[0, 0, 0], [0.5, 0, 0], [-1, 1, 0]], [1 / 6, 2 / 3, 1 / 6])) == 1
    # rk4 with the last stage at the midpoint instead of the end
    bad = mslab.ExplicitRK([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 0.5, 0]],
                           [1 / 6, 1 / 3, 1 / 3, 1 / 6])
    assert derive.order(bad) < 4


def test_order_reads_the_stepping_tableau():
    rk4 = mslab.get_method("rk4")
    assert derive.order(mslab.ExplicitRK(rk4.A, rk4.b, rk4.c)) == 4


def test_too_high_order_is_reported():
    with pytest.raises(ValueError, match="order > 3"):
        derive.order("rk4", max_order=3)


@pytest.mark.parametrize("name, expected", [
    ("euler", 1 + z),                                               # seed eq. 32
    ("heun", 1 + z + z**2 / 2),
    ("rk4", 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24),
    ("implicit_euler", 1 / (1 - z)),
    ("implicit_midpoint", (1 + z / 2) / (1 - z / 2)),
])
def test_stability_function(name, expected):
    assert same(derive.stability_function(name), expected)


@pytest.mark.parametrize("name", ["symplectic_euler", "symplectic_euler_x", "leapfrog", "velocity_verlet"])
def test_leading_term_predicts_one_numerical_step(name):
    """One real step on x'' = -w^2 u: the error divided by the leading term tends to 1."""
    w, u0, v0 = 3.0, 0.2, 0.7
    scene = oscillator(stiffness=w * w, mass=1.0, displacement=u0, velocity=v0)
    method = mslab.get_method(name)
    lead = derive.analyse(name)
    subs = {v: v0, a: -w * w * u0, a1: -w * w, a2: 0}
    for dt in (1e-3, 2e-3):
        state = method.step(scene.system, method.start(scene.system, scene.state0, dt), dt)
        x_ex, v_ex = scene.exact(dt)
        err = np.array([x_ex[0, 1, 0] - state.x[1, 0], v_ex[0, 1, 0] - state.v[1, 0]])
        predicted = np.array([float(c.subs(subs).subs(h, dt)) for c in lead.leading])
        scale = np.max(np.abs(predicted))
        assert np.allclose(err, predicted, rtol=0, atol=20 * dt * scale)


def test_reachable_as_mslab_derive():
    assert mslab.derive.order("heun") == 2
    assert mslab.derive is derive


@pytest.mark.parametrize("a21, b", [
    (0.5, [0.0, 1.0]),       # sum b = 1, b2 a21 = 1/2: order 2 (midpoint)
    (0.25, [0.0, 1.0]),      # sum b = 1, b2 a21 = 1/4: order 1
    (1.0, [0.5, 0.25]),      # sum b = 3/4: not even consistent, order 0
    (0.75, [1 / 3, 2 / 3]),  # b2 a21 = 1/2: order 2 (a Ralston-like pair)
])
def test_two_stage_order_conditions(a21, b):
    # hand conditions: order >= 1 iff b1 + b2 = 1; order 2 iff also b2 a21 = 1/2;
    # never 3 with two stages (b2 a21^2 = 1/3 and the f'^2 f term cannot both hold)
    expected = 0 if abs(sum(b) - 1) > 1e-12 else (2 if abs(b[1] * a21 - 0.5) < 1e-12 else 1)
    assert derive.order(mslab.ExplicitRK([[0, 0], [a21, 0]], b)) == expected


def test_taylor_backward_and_velocity_series():
    x = sp.Symbol("x")
    back = derive.taylor(3, "second", -h)
    assert same(back, x - h * v + h**2 / 2 * a - h**3 / 6 * a1 * v)
    assert same(derive.taylor(2, "velocity", h / 2), v + h / 2 * a + h**2 / 8 * a1 * v)
    with pytest.raises(ValueError):
        derive.taylor(2, "third")

