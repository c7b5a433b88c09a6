"""mslab.derive: orders and local errors from Taylor expansions, against hand derivations."""

import time
import warnings
from fractions import Fraction
from types import SimpleNamespace

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
    ("euler", h**2 / 2 * f * f1),                                    # y''/2 h^2, eq. 6 of the lecture notes
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
    # eqs. 21-23 of the lecture notes: the odd terms cancel, h^4/12 x'''' remains
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
    ("euler", 1 + z),                                               # eq. 32 of the lecture notes
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



# -- exact orders: rooted-tree order conditions on the coefficients as given ------------
def rk_method(A, b, name="tableau", family="explicit_rk"):
    """A stand-in method object with the Runge-Kutta interface mslab.derive reads."""
    return SimpleNamespace(name=name, family=family, order=0,
                           A=np.array([[float(sp.N(sp.sympify(a))) for a in row] for row in A]),
                           b=np.array([float(sp.N(sp.sympify(w))) for w in b]), c=None,
                           coefficients={"A": tuple(tuple(row) for row in A), "b": tuple(b), "c": None})


def splitting(drift, kick, name="splitting"):
    """A stand-in splitting (drift first) with the interface mslab.derive reads."""
    return SimpleNamespace(name=name, family="splitting", order=0,
                           drift=np.array([float(sp.N(sp.sympify(a))) for a in drift]),
                           kick=np.array([float(sp.N(sp.sympify(b))) for b in kick]),
                           coefficients={"drift": tuple(drift), "kick": tuple(kick)})


def floats(rows):
    return [[float(sp.N(sp.sympify(a))) for a in row] for row in rows]


#: Dormand & Prince, J. Comput. Appl. Math. 6 (1980) 19-26, RK5(4)7M (the order-5 weights).
DP5_A = [[0] * 7, ["1/5", 0, 0, 0, 0, 0, 0], ["3/40", "9/40", 0, 0, 0, 0, 0],
         ["44/45", "-56/15", "32/9", 0, 0, 0, 0],
         ["19372/6561", "-25360/2187", "64448/6561", "-212/729", 0, 0, 0],
         ["9017/3168", "-355/33", "46732/5247", "49/176", "-5103/18656", 0, 0],
         ["35/384", 0, "500/1113", "125/192", "-2187/6784", "11/84", 0]]
DP5_B = ["35/384", 0, "500/1113", "125/192", "-2187/6784", "11/84", 0]


def test_the_issues_two_stage_example_as_an_explicit_rk():
    a = 1 / np.sqrt(2)                    # order 2, was reported 1
    assert derive.order(mslab.ExplicitRK([[0, 0], [a, 0]], [1 - 1 / (2 * a), 1 / (2 * a)])) == 2


@pytest.mark.parametrize("form", ["strings", "fractions", "sympy", "floats"])
def test_dopri5_in_every_form_has_order_5(form):
    if form == "strings":
        A, b = DP5_A, DP5_B
    elif form == "fractions":
        A, b = [[Fraction(str(a)) for a in r] for r in DP5_A], [Fraction(str(w)) for w in DP5_B]
    elif form == "sympy":
        A, b = [[sp.Rational(str(a)) for a in r] for r in DP5_A], [sp.Rational(str(w)) for w in DP5_B]
    else:
        A, b = floats(DP5_A), floats([DP5_B])[0]
    assert derive.order(rk_method(A, b, "dopri5")) == 5


def test_one_coefficient_off_by_1e6_lowers_the_order():
    A, b = floats(DP5_A), floats([DP5_B])[0]
    bad = [row[:] for row in A]
    bad[3][2] += 1e-6                     # c4 moves: sum b_i c_i = 1/2 fails by b4 1e-6
    assert derive.order(rk_method(bad, b)) == 1
    bad[3][0] -= 1e-6                     # row sums kept: sum b_i a_ij c_j = 1/6 fails
    assert derive.order(rk_method(bad, b)) == 2
    exact = [[Fraction(str(a)) for a in r] for r in DP5_A]
    exact[3][2] += Fraction(1, 10**6)
    exact[3][0] -= Fraction(1, 10**6)
    assert derive.order(rk_method(exact, [Fraction(str(w)) for w in DP5_B])) == 2


@pytest.mark.parametrize("a", [1 / sp.sqrt(2), 1 / np.sqrt(2), "1/sqrt(2)", sp.Rational(2, 3), 0.75])
def test_two_stage_family_is_order_2_for_every_a(a):
    # b2 a = 1/2 and b1 + b2 = 1 for every a != 0: order 2 (the issue's a = 1/sqrt(2) gave 1)
    ae = sp.sympify(a) if isinstance(a, str) else a
    b = [1 - 1 / (2 * ae), 1 / (2 * ae)]
    assert derive.order(rk_method([[0, 0], [ae, 0]], b)) == 2
    if isinstance(a, str):                # also all as strings
        assert derive.order(rk_method([[0, 0], [a, 0]], ["1 - sqrt(2)/2", "sqrt(2)/2"])) == 2


g = 1 - 1 / sp.sqrt(2)
s3 = sp.sqrt(3)
IMPLICIT = {
    # Gauss-Legendre 2 stages, order 2s = 4 (Butcher 1964; Hairer-Wanner II, Table IV.5.1)
    "gauss2": ([["1/4", sp.Rational(1, 4) - s3 / 6], [sp.Rational(1, 4) + s3 / 6, "1/4"]], ["1/2", "1/2"], 4),
    # Radau IIA 2 stages, order 2s - 1 = 3 (Hairer-Wanner II, Table IV.5.5)
    "radau_iia2": ([["5/12", "-1/12"], ["3/4", "1/4"]], ["3/4", "1/4"], 3),
    # SDIRK, gamma = 1 - 1/sqrt(2): L-stable, order 2 (Alexander 1977; Hairer-Wanner II, IV.6)
    "sdirk2": ([[g, 0], [1 - g, g]], [1 - g, g], 2),
    "implicit_euler": ([[1]], [1], 1),
    "implicit_midpoint": ([["1/2"]], [1], 2),
}


@pytest.mark.parametrize("name", list(IMPLICIT))
@pytest.mark.parametrize("form", ["exact", "floats"])
def test_implicit_tableaux(name, form):
    A, b, p = IMPLICIT[name]
    if form == "floats":
        A, b = floats(A), floats([b])[0]
    assert derive.order(rk_method(A, b, name, "implicit_rk")) == p


@pytest.mark.parametrize("name, expected", [
    ("gauss2", (1 + z / 2 + z**2 / 12) / (1 - z / 2 + z**2 / 12)),     # (2,2) Padé approximant
    ("radau_iia2", (1 + z / 3) / (1 - 2 * z / 3 + z**2 / 6)),          # (1,2) Padé approximant
    ("implicit_midpoint", (1 + z / 2) / (1 - z / 2)),
])
def test_stability_function_of_implicit_tableaux(name, expected):
    A, b, _ = IMPLICIT[name]
    assert same(derive.stability_function(rk_method(A, b, name, "implicit_rk")), expected)


def test_sdirk2_is_l_stable_exactly():
    A, b, _ = IMPLICIT["sdirk2"]
    R = derive.stability_function(rk_method(A, b, "sdirk2", "implicit_rk"))
    assert sp.limit(R, z, -sp.oo) == 0 and sp.simplify(R.subs(z, 0)) == 1


def test_implicit_midpoint_local_error_from_its_tableau():
    # y1 = y + h f((y + y1)/2) = y + h f + h^2/2 f'f + h^3 (f'^2 f/4 + f'' f^2/8) + ...,
    # the exact h^3 term is (f'' f^2 + f'^2 f)/6
    A, b, _ = IMPLICIT["implicit_midpoint"]
    expected = h**3 * (f2 * f**2 / 24 - f * f1**2 / 12)
    assert same(derive.local_error(rk_method(A, b, "im", "implicit_rk")), expected)


def test_bad_coefficients_are_one_line_errors():
    with pytest.raises(ValueError, match="not a number"):
        derive.order(SimpleNamespace(name="x", coefficients={"A": ((0,),), "b": ("one",), "c": None}))
    with pytest.raises(ValueError, match="1 x 1"):
        derive.order(SimpleNamespace(name="x", coefficients={"A": ((0, 0),), "b": (1,), "c": None}))


# -- splittings: x += a_i h v, v += b_i h a(x), drift first --------------------------------
THETA = 1 / (2 - sp.root(2, 3))
#: Yoshida, Phys. Lett. A 150 (1990) 262-268, Table 1, solution A: the order-6 symmetric
#: composition w3 w2 w1 w0 w1 w2 w3 of Störmer-Verlet steps, w0 = 1 - 2 (w1 + w2 + w3).
YOSHIDA_W = (-1.17767998417887, 0.235573213359357, 0.784513610477560)


def composition(weights):
    """Drift/kick coefficients of Störmer-Verlet (drift h/2, kick h, drift h/2) composed."""
    drift = [weights[0] / 2] + [(weights[i] + weights[i + 1]) / 2 for i in range(len(weights) - 1)]
    return drift + [weights[-1] / 2], list(weights)


def yoshida6():
    w1, w2, w3 = YOSHIDA_W
    return composition([w3, w2, w1, 1 - 2 * (w1 + w2 + w3), w1, w2, w3])


SPLITTINGS = {
    # velocity first (lecture notes, eqs. 9-10): the first drift is empty, v += h a(x), x += h v
    "symplectic_euler": (([0, 1], [1]), 1),
    "symplectic_euler_x": (([1, 0], [1]), 1),          # position first, eqs. 7-8
    "stormer_verlet": ((["1/2", "1/2"], [1]), 2),      # drift-kick-drift
    "velocity_verlet": (([0, 1, 0], ["1/2", "1/2"]), 2),  # kick-drift-kick
    # Forest & Ruth, Physica D 43 (1990) 105: theta = 1/(2 - 2^(1/3))
    "forest_ruth": (([THETA / 2, (1 - THETA) / 2, (1 - THETA) / 2, THETA / 2],
                     [THETA, 1 - 2 * THETA, THETA]), 4),
    "yoshida6": (yoshida6(), 6),
}


@pytest.mark.parametrize("name", list(SPLITTINGS))
@pytest.mark.parametrize("form", ["given", "floats"])
def test_splitting_orders(name, form):
    (drift, kick), p = SPLITTINGS[name]
    if form == "floats":
        drift, kick = floats([drift])[0], floats([kick])[0]
    assert derive.order(splitting(drift, kick, name)) == p


def test_perturbed_forest_ruth_loses_its_order():
    (drift, kick), _ = SPLITTINGS["forest_ruth"]
    drift, kick = floats([drift])[0], floats([kick])[0]
    drift[1] += 1e-6
    drift[2] -= 1e-6                      # sum of drifts kept: consistent, order 4 lost
    assert derive.order(splitting(drift, kick)) < 4


def _step(drift, kick, x, v, h):
    for i, a in enumerate(drift):
        x = x + a * h * v
        if i < len(kick):
            v = v - kick[i] * h * np.sin(x)
    return x, v


@pytest.mark.parametrize("name", ["symplectic_euler", "stormer_verlet", "forest_ruth", "yoshida6"])
def test_splitting_order_matches_the_convergence_slope(name):
    """Independent truth: the fitted global error slope on the pendulum x'' = -sin x."""
    from scipy.integrate import solve_ivp

    (drift, kick), p = SPLITTINGS[name]
    drift, kick = floats([drift])[0], floats([kick])[0]
    x0, v0, t_end = 1.0, 0.5, 2.0
    ref = solve_ivp(lambda t, y: [y[1], -np.sin(y[0])], (0, t_end), [x0, v0], method="DOP853",
                    rtol=1e-13, atol=1e-13).y[:, -1]
    errors, hs = [], [t_end / n for n in (8, 16, 32)] if p >= 4 else [t_end / n for n in (50, 100, 200)]
    for hh in hs:
        x, v = x0, v0
        for _ in range(round(t_end / hh)):
            x, v = _step(drift, kick, x, v, hh)
        errors.append(np.hypot(x - ref[0], v - ref[1]))
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert abs(slope - p) < 0.3, (slope, errors)
    assert derive.order(splitting(drift, kick, name)) == p


def test_adapters_report_the_order_of_their_splitting():
    (drift, kick), _ = SPLITTINGS["stormer_verlet"]
    for family in ("two_step", "staggered"):
        adapter = SimpleNamespace(name="adapter", family=family, order=2, splitting=splitting(drift, kick))
        assert derive.order(adapter) == 2


def test_splitting_local_error_matches_the_stepping_code():
    # kick-drift-kick from its coefficients = the velocity Verlet class run symbolically
    (drift, kick), _ = SPLITTINGS["velocity_verlet"]
    from_coefficients = derive.analyse(splitting(drift, kick, "kdk"))
    assert from_coefficients.order == 2
    assert same(from_coefficients.leading[0], derive.local_error("velocity_verlet")[0])
    assert same(from_coefficients.leading[1], derive.local_error("velocity_verlet")[1])
    assert same(derive.analyse(splitting([0, 1], [1])).leading[0], -h**2 / 2 * a)


# -- a published tableau library: nodepy (test-only dependency) ---------------------------
#: Orders nodepy states for its explicit methods, from the names and descriptions of
#: ``loadRKM`` ("RK5(4)7": order 5, embedded 4; "SSP 54": Ruuth-Spiteri SSP(5,4); "Optimal
#: 3rd-order SSP ..."). Pairs: (order of b, order of the embedded bhat).
NODEPY_STATED = {
    "FE": 1, "SSP22": 2, "Heun22": 2, "MTE22": 2, "Mid22": 2, "SSP22star": 2, "SSP33": 3,
    "Heun33": 3, "NSSP32": 2, "NSSP33": 3, "SSP43": 3, "SSP104": 4, "RK44": 4, "BuRK65": 5,
    "Fehlberg45": (5, 4), "Fehlberg43": (4, 3), "Merson43": (4, 3), "Soderlind43": (4, 3),
    "Zonneveld43": (4, 3), "Tsit5": (5, 4), "CK5": (5, 4), "HH5": (5, 4), "HH5S": (5, 4),
    "DP5": (5, 4), "CMR6": (6, 5), "BS3": (3, 2), "BS5": (5, 4), "PD8": (8, 7),
    "SSP75": 5, "SSP85": 5, "SSP95": 5, "SSP54": 4, "SSP63": 3,
    # implicit: Gauss s stages 2s, Radau IIA 2s - 1, Lobatto IIIA/IIIC 2s - 2 (Hairer-Wanner
    # II, sec. IV.5); SDIRK23/34 "3rd-/4th-order SDIRK method of Norsett", SDIRK54 (Hairer-
    # Wanner II, Table IV.6.5), TR-BDF2 "2nd-order, L-stable DIRK method of Bank et al."
    "BE": 1, "GL2": 4, "GL3": 6, "RadauIIA2": 3, "RadauIIA3": 5, "LobattoIIIA2": 2,
    "LobattoIIIA3": 4, "LobattoIIIC2": 2, "LobattoIIIC3": 4, "LobattoIIIC4": 6,
    "SDIRK23": 3, "SDIRK34": 4, "SDIRK54": 4, "TR-BDF2": 2,
}
#: Where nodepy's data disagree with its own statement (see test_nodepy_disagreements).
NODEPY_DISAGREE = {"SS3", "SSP53"}


@pytest.fixture(scope="module")
def nodepy_methods():
    rkm = pytest.importorskip("nodepy.runge_kutta_method")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rkm, rkm.loadRKM("All")


def _forms(A, b):
    """The tableau as stored (exact sympy where nodepy has it), as Fractions, as floats."""
    yield "floats", floats(A), floats([b])[0]
    if all(isinstance(x, sp.Basic) for x in [*np.ravel(A), *b]):
        yield "exact", [list(r) for r in A], list(b)
        if all(sp.sympify(x).is_Rational for x in [*np.ravel(A), *b]):
            yield "fractions", [[Fraction(str(x)) for x in r] for r in A], [Fraction(str(x)) for x in b]


def test_nodepy_stated_orders(nodepy_methods):
    _, library = nodepy_methods
    checked = 0
    for key, stated in NODEPY_STATED.items():
        m = library[key]
        pairs = [(m.b, stated if isinstance(stated, int) else stated[0])]
        if not isinstance(stated, int):
            pairs.append((m.bhat, stated[1]))
        for weights, p in pairs:
            for form, A, b in _forms(m.A, weights):
                family = "explicit_rk" if m.is_explicit() else "implicit_rk"
                assert derive.order(rk_method(A, b, key, family)) == p, (key, form)
            checked += m.is_explicit()
    assert checked >= 45


#: nodepy's constructors with the order their docstrings state.
def _families(rkm):
    out = {f"SSPRK2({m})": (rkm.SSPRK2(m), 2) for m in (2, 3, 4, 5)}
    out.update({f"SSPRK3({m})": (rkm.SSPRK3(m), 3) for m in (4, 9)})
    out.update({f"extrap({k})": (rkm.extrap(k), k) for k in (2, 3, 4, 5)})          # Euler base
    out.update({f"extrap({k},midpoint)": (rkm.extrap(k, "midpoint"), 2 * k) for k in (2, 3)})
    out.update({f"DC({s})": (rkm.DC(s), s + 1) for s in (1, 2, 3)})                 # deferred correction
    out.update({f"RKC1({m})": (rkm.RKC1(m), 1) for m in (2, 3, 5)})
    out.update({f"RKC2({m})": (rkm.RKC2(m), 2) for m in (2, 3, 5)})
    out["RK44_family(1)"] = (rkm.RK44_family(1), 4)
    return out


def test_nodepy_families(nodepy_methods):
    rkm, _ = nodepy_methods
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        families = _families(rkm)
    for key, (m, p) in families.items():
        for form, A, b in _forms(m.A, m.b):
            assert derive.order(rk_method(A, b, key)) == p, (key, form)


def test_nodepy_disagreements(nodepy_methods):
    _, library = nodepy_methods
    # SS3 "Sharp-Smart RK3(2)4": nodepy stores the order-2 weights as b and the order-3
    # ones as bhat (its own order() also gives 2 for b)
    ss3 = library["SS3"]
    assert derive.order(rk_method(ss3.A.tolist(), list(ss3.b))) == 2
    assert derive.order(rk_method(ss3.A.tolist(), list(ss3.bhat))) == 3
    # SSP53 (Ruuth-Spiteri SSP(5,3)) is stored with 14 decimals that are off by ~1e-10:
    # sum b - 1 = 3.2e-10, far above round-off: as given it is not even consistent
    ssp53 = library["SSP53"]
    b = floats([ssp53.b])[0]
    assert abs(sum(b) - 1) > 1e-10
    assert derive.order(rk_method(floats(ssp53.A), b)) == 0


def test_nodepy_own_order_as_second_opinion(nodepy_methods):
    _, library = nodepy_methods
    for key in NODEPY_STATED:
        m = library[key]
        ours = derive.order(rk_method(floats(m.A), floats([m.b])[0], key))
        # nodepy's order() uses an absolute tolerance of 1e-14; Tsit5's fifth-order
        # conditions have terms up to 2.5e6 and residuals of 1.4e-14 (round-off): a
        # tolerance of 1e-13 gives 5, as stated
        theirs = m.order(tol=1e-13) if key == "Tsit5" else m.order()
        assert ours == theirs, key


def test_order_of_13_stage_tableaux(nodepy_methods):
    """Worst cases: every condition through order 9 evaluated on dense 13 x 13 tableaux.

    How long it takes is printed, not asserted (no test depends on timing, issue 18).
    """
    _, library = nodepy_methods
    pd8 = library["PD8"]                               # Prince-Dormand 8(7), 13 stages, floats
    start = time.perf_counter()
    assert derive.order(rk_method(floats(pd8.A), floats([pd8.b])[0], "pd8")) == 8
    float_time = time.perf_counter() - start
    # collocation at 13 equispaced rational nodes (implicit, dense, exact): order >= 13
    t = sp.Symbol("t")
    nodes = [sp.Rational(i, 12) for i in range(13)]
    lagrange = [sp.prod([(t - ck) / (cj - ck) for ck in nodes if ck != cj]) for cj in nodes]
    antider = [sp.Poly(sp.expand(lj), t).integrate() for lj in lagrange]
    A = [[L.eval(ci) for L in antider] for ci in nodes]
    b = [L.eval(1) for L in antider]
    start = time.perf_counter()
    with pytest.raises(ValueError, match="order > 8"):
        derive.order(rk_method(A, b, "collocation13", "implicit_rk"))
    exact_time = time.perf_counter() - start
    print(f"13 stages: PD8 floats {float_time:.3f} s, dense exact collocation {exact_time:.3f} s")
