"""mslab.stability against closed forms, against the stepping code, and against real runs."""

import math
import warnings

import numpy as np
import pytest
import sympy
from scipy.optimize import brentq

import mslab
from mslab import stability as st
from mslab.scenes.generators import chain, cloth, oscillator

RNG = np.random.default_rng(4)
Z = RNG.normal(size=40) * 2 + 1j * RNG.normal(size=40) * 2

CLOSED = {
    "euler": lambda z: 1 + z,
    "heun": lambda z: 1 + z + z**2 / 2,
    "midpoint": lambda z: 1 + z + z**2 / 2,
    "rk3": lambda z: 1 + z + z**2 / 2 + z**3 / 6,
    "rk4": lambda z: 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24,
    "implicit_euler": lambda z: 1 / (1 - z),
    "implicit_euler_fp": lambda z: 1 / (1 - z),
    "implicit_midpoint": lambda z: (1 + z / 2) / (1 - z / 2),
}
PARTITIONED = ["symplectic_euler", "symplectic_euler_x", "verlet", "leapfrog", "velocity_verlet"]


@pytest.mark.parametrize("method", sorted(CLOSED))
def test_R_matches_closed_form(method):
    np.testing.assert_allclose(st.amplification(method, Z), CLOSED[method](Z), rtol=1e-13)


@pytest.mark.parametrize("method", sorted(CLOSED))
def test_sympy_R_matches_closed_form(method):
    z = sympy.Symbol("z")
    expr = st.amplification_sympy(method)
    exact = CLOSED[method](z) if "implicit" not in method else CLOSED[method](sympy.Integer(1) * z)
    assert sympy.simplify(expr - sympy.nsimplify(exact)) == 0


RK_METHODS = [m for m in mslab.methods() if "A" in mslab.get_method(m).coefficients]


@pytest.mark.parametrize("method", RK_METHODS)
def test_R_is_the_determinant_formula_in_every_number_type(method):
    """The one stability polynomial (floats, Fractions, sympy) = ``det(I - zA + z 1 b^T) / det(I - zA)``."""
    from fractions import Fraction

    from mslab.integrators.families.polynomials import stability_polynomials

    m = mslab.get_method(method)
    s = m.n_stages
    mats = np.eye(s)[None] - Z[:, None, None] * m.A[None]
    direct = np.linalg.det(mats + Z[:, None, None] * np.outer(np.ones(s), m.b)[None]) / np.linalg.det(mats)
    np.testing.assert_allclose(m.stability_function(Z), direct, rtol=1e-12)
    for number in (float, Fraction, sympy.nsimplify):
        N, D = stability_polynomials([[number(a) for a in row] for row in m.A.tolist()],
                                     [number(w) for w in m.b.tolist()])
        num, den = (np.polynomial.polynomial.polyval(Z, np.array(p, dtype=complex)) for p in (N, D))
        np.testing.assert_allclose(num / den, direct, rtol=1e-12)


def test_sympy_refuses_partitioned_methods():
    with pytest.raises(TypeError, match="amplification_matrix"):
        st.amplification_sympy("verlet")


def test_amplification_is_vectorised_over_shapes():
    z = Z.reshape(5, 8)
    for method in ("rk4", "verlet", "implicit_midpoint"):
        assert st.amplification(method, z).shape == (5, 8)


POINTS = [(0.3, 0.0), (0.9, 0.0), (1.7, 0.0), (1.3, 0.2), (0.6, 0.05), (2.5, 1.0)]


@pytest.mark.parametrize("method", mslab.methods())
def test_measured_map_equals_theory(method):
    """The amplification matrix written from the update equations = the one the real step makes."""
    for h_omega, h_gamma in POINTS:
        if method == "implicit_euler_fp" and h_omega > 0.8:
            continue  # the fixed-point iteration only converges for dt |lam| < 1
        theory = st.amplification_matrix(method, h_omega, h_gamma)
        measured = st.measured_amplification_matrix(method, h_omega, h_gamma)
        tol = 1e-6 if method == "implicit_euler_fp" else 1e-10
        assert st.same_spectrum(theory, measured) < tol, (method, h_omega, h_gamma)
        rho_t = st.spectral_radius(theory)
        rho_m = st.spectral_radius(measured)
        assert rho_t == pytest.approx(rho_m, rel=tol, abs=tol)


@pytest.mark.parametrize("method", sorted(set(CLOSED) - {"implicit_euler_fp"}))
def test_matrix_of_RK_method_has_eigenvalues_R(method):
    """For a tableau, the oscillator map is R(dt J): its eigenvalues are R(z), R(conj z)."""
    h_omega, h_gamma = 1.1, 0.3
    lam = np.roots([1.0, h_gamma, h_omega**2])
    mu = np.linalg.eigvals(st.amplification_matrix(method, h_omega, h_gamma))
    expected = CLOSED[method](lam)
    assert st.same_spectrum(np.diag(mu), np.diag(expected)) < 1e-12


@pytest.mark.parametrize("method", PARTITIONED)
def test_partitioned_R_is_largest_eigenvalue_of_the_oscillator_map(method):
    z = -0.3 + 1.2j  # the oscillator with eigenvalues z, conj z: w^2 = |z|^2, gamma = -2 Re z
    mats = st.measured_amplification_matrix(method, abs(z), -2 * z.real)
    assert abs(st.amplification(method, z)) == pytest.approx(st.spectral_radius(mats), rel=1e-10)


# -- limits, against values computed independently here ------------------------------------------

def _poly_root(method, lo, hi, direction):
    return brentq(lambda s: abs(CLOSED[method](direction * s)) - 1.0, lo, hi, xtol=1e-14)


def test_real_intervals():
    assert st.real_interval("euler") == pytest.approx(-2.0, abs=1e-8)
    assert st.real_interval("heun") == pytest.approx(-2.0, abs=1e-8)
    assert st.real_interval("midpoint") == pytest.approx(-2.0, abs=1e-8)
    assert st.real_interval("rk4") == pytest.approx(-_poly_root("rk4", 2.5, 3.0, -1), abs=1e-8)
    assert st.real_interval("rk4") == pytest.approx(-2.785, abs=1e-3)
    assert st.real_interval("rk3") == pytest.approx(-_poly_root("rk3", 2.0, 3.0, -1), abs=1e-8)
    for m in ("implicit_euler", "implicit_euler_fp", "implicit_midpoint"):
        assert st.real_interval(m) == -np.inf


def test_imag_limits():
    assert st.imag_limit("euler") == 0.0
    assert st.imag_limit("heun") == 0.0
    assert st.imag_limit("midpoint") == 0.0
    assert st.imag_limit("rk4") == pytest.approx(2 * math.sqrt(2), abs=1e-8)
    assert st.imag_limit("rk4") == pytest.approx(_poly_root("rk4", 2.5, 3.0, 1j), abs=1e-8)
    assert st.imag_limit("rk3") == pytest.approx(math.sqrt(3), abs=1e-8)
    for m in ("implicit_euler", "implicit_midpoint"):
        assert st.imag_limit(m) == np.inf


def _measured_oscillator_limit(method):
    """Bisection on the spectral radius of the map measured from the real step."""
    def stable(w):
        return st.spectral_radius(st.measured_amplification_matrix(method, w, 0.0, delta=1e-3)) <= 1 + 1e-7

    lo, hi = 0.5, 6.0
    assert stable(lo) and not stable(hi)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def test_forest_ruth_limit_from_its_coefficients_and_from_real_steps():
    """Forest-Ruth: about 1.5734 (Forest & Ruth 1990), from the product of shear matrices and measured."""
    assert st.oscillator_limit("forest_ruth") == pytest.approx(1.5734, abs=1e-4)
    measured = _measured_oscillator_limit("forest_ruth")
    assert st.oscillator_limit("forest_ruth") == pytest.approx(measured, abs=1e-5)


def _measured_first_limit(method, step=0.01):
    """The first instability of the real step: scan h w upwards, then bisect (stability may return later)."""
    def stable(w):
        return st.spectral_radius(st.measured_amplification_matrix(method, w, 0.0, delta=1e-3)) <= 1 + 1e-7

    lo = step
    while stable(lo + step):
        lo += step
    hi = lo + step
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def test_every_method_without_R_is_checked_against_its_real_step():
    """The registry decides which methods are partitioned; each one's limit = the real step's first one.

    Yoshida's sixth-order method is unstable near h w = 2.28 and stable again up to 2.8: the limit
    is the first instability.
    """
    partitioned = [m for m in mslab.methods() if mslab.get_method(m).stability_function(np.zeros(1)) is None]
    assert set(PARTITIONED) <= set(partitioned)
    for m in partitioned:
        assert st.oscillator_limit(m) == pytest.approx(_measured_first_limit(m), abs=1e-5), m


@pytest.mark.parametrize("method", PARTITIONED + ["rk4"])
def test_oscillator_limit_against_bisection_on_the_real_step(method):
    expected = 2.0 if method in PARTITIONED else 2 * math.sqrt(2)
    assert st.oscillator_limit(method) == pytest.approx(expected, abs=1e-7)
    assert st.oscillator_limit(method) == pytest.approx(_measured_oscillator_limit(method), abs=1e-5)


def test_oscillator_limits_of_unstable_and_implicit_methods():
    for m in ("euler", "heun", "midpoint"):
        assert st.oscillator_limit(m) == 0.0  # |R(i y)| > 1 for every y > 0
    for m in ("implicit_euler", "implicit_euler_fp", "implicit_midpoint"):
        assert st.oscillator_limit(m) == np.inf


def test_summary_rows():
    rows = st.summary(["euler", "rk4"])
    assert [r["method"] for r in rows] == ["euler", "rk4"]
    assert rows[1]["imag_limit"] == st.imag_limit("rk4")


# -- step limits of scenes ----------------------------------------------------------------------

def test_max_stable_dt_on_the_oscillator_is_limit_over_omega():
    scene = oscillator(stiffness=400.0, mass=1.0)  # w = 20
    for m in mslab.methods():
        if m == "implicit_euler_fp":
            assert st.max_stable_dt(scene, m) == pytest.approx(1 / 20)  # contraction limit
        else:
            assert st.max_stable_dt(scene, m) == pytest.approx(st.oscillator_limit(m) / 20, rel=1e-9)


def test_max_stable_dt_of_euler_on_a_damped_oscillator():
    """Forward Euler: |1 + h lam| <= 1 with lam = -beta +- i wd gives h = 2 beta / w0^2 = gamma / k."""
    k, gamma = 100.0, 2.0
    scene = oscillator(stiffness=k, mass=1.0, gamma=gamma)
    assert st.max_stable_dt(scene, "euler") == pytest.approx(gamma / k, rel=1e-8)
    assert st.max_stable_dt(scene, "implicit_euler") == np.inf


def test_collider_stiffness_limits_the_step():
    b = mslab.SceneBuilder(2)
    a = b.add_particle([0.0, 1.0], pinned=True)
    p = b.add_particle([0.0, 0.5], mass=2.0)
    b.add_spring(a, p, stiffness=50.0)
    b.add_plane(normal=[0, 1], offset=0.0, stiffness=5000.0)  # not touching at state0
    scene = b.build()
    w = math.sqrt(5000.0 / 2.0)  # the plane, with the spring's 50 added along the same axis
    w_both = math.sqrt(5050.0 / 2.0)
    assert st.max_stable_dt(scene, "verlet") == pytest.approx(2 / w_both, rel=1e-9)
    active = st.max_stable_dt(scene, "verlet", contacts="active")
    assert active == pytest.approx(2 / math.sqrt(25.0), rel=1e-9)
    assert 2 / w_both < 2 / w


def _true_limit(scene, method, guess, steps=1500):
    """Bisection with real runs: the largest dt whose energy error stays below twice its scale."""
    ref = mslab.simulate(scene, method, dt=0.5 * guess, t_end=0.5 * guess * steps, save_every=10,
                         check_stability=False)
    scale = float(np.max(ref.energy.kinetic + np.abs(ref.energy.potential)))

    def stable(dt):
        try:
            tr = mslab.simulate(scene, method, dt=dt, t_end=dt * steps, save_every=10, blowup=10,
                                check_stability=False)
        except mslab.InstabilityError:
            return False
        return float(np.max(np.abs(tr.energy.total - tr.energy.total[0]))) < 2.0 * scale

    lo, hi = 0.5 * guess, 2.0 * guess
    assert stable(lo) and not stable(hi)
    for _ in range(8):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return math.sqrt(lo * hi)


@pytest.mark.parametrize("name", ["chain", "cloth", "damped_chain"])
@pytest.mark.parametrize("method", ["symplectic_euler", "verlet", "rk4"])
def test_max_stable_dt_within_10_percent_of_real_runs(name, method):
    scene = {"chain": lambda: chain(12, stiffness=2e3),
             "cloth": lambda: cloth(5, 5),
             "damped_chain": lambda: chain(12, stiffness=2e3, gamma=0.3)}[name]()
    predicted = st.max_stable_dt(scene, method)
    actual = _true_limit(scene, method, predicted)
    assert abs(actual / predicted - 1) < 0.10, (predicted, actual)


def test_simulate_warns_above_the_prediction_and_counts_nothing():
    scene = oscillator(stiffness=1e4, displacement=0.1, t_end=0.2)  # w = 100: rk4 limit 0.0283
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        quiet = mslab.simulate(scene, "rk4", dt=0.02)
    off = mslab.simulate(scene, "rk4", dt=0.02, check_stability=False)
    assert quiet.stats.n_force == off.stats.n_force == 4 * 10 and quiet.stats.n_jac == 0
    with pytest.warns(mslab.StabilityWarning, match="0.02828"):
        with pytest.raises(mslab.InstabilityError) as info:
            mslab.simulate(scene.with_settings(t_end=2.0), "rk4", dt=0.04)
    assert info.value.stable_dt == pytest.approx(2 * math.sqrt(2) / 100, rel=1e-6)
    assert "predicted stable dt = 0.02828" in str(info.value)


def test_no_check_for_implicit_methods():
    scene = oscillator(stiffness=1e4, displacement=0.1, t_end=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mslab.simulate(scene, "implicit_euler", dt=0.1)


# -- command line and plots ---------------------------------------------------------------------

def test_cli_stability_json_and_figure(tmp_path, capsys):
    import json

    from mslab.cli import main

    assert main(["stability", "rk4", "verlet", "implicit-euler", "--json", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    rows = {r["method"]: r for r in doc["methods"]}
    assert set(rows) == {"rk4", "verlet", "implicit_euler"}
    assert rows["rk4"]["imag_limit"] == pytest.approx(2 * math.sqrt(2), abs=1e-8)
    assert rows["verlet"]["oscillator_limit"] == pytest.approx(2.0, abs=1e-8)
    assert rows["implicit_euler"]["real_interval"] is None  # -inf is not JSON: null
    assert (tmp_path / "stability_regions.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "stability.json").read_text())["methods"][0]["method"] == "rk4"


def test_cli_stability_table_all_and_bad_method(capsys):
    from mslab.cli import main

    assert main(["stability"]) == 0
    out = capsys.readouterr().out
    for name in mslab.methods():
        assert name in out
    assert main(["stability", "rk5"]) == 2
    assert "unknown method 'rk5'" in capsys.readouterr().err


def test_plots_draw_on_the_given_axes():
    import matplotlib.pyplot as plt

    from mslab.plots import plot_oscillator_stability, plot_stability_regions

    fig, (a, b) = plt.subplots(1, 2)
    assert plot_stability_regions(["euler", "rk4"], ax=a, n=61) is a
    assert plot_oscillator_stability(["euler", "verlet"], ax=b, n=50) is b
    assert "lambda" in a.get_xlabel() and "omega" in b.get_xlabel()
    assert len(b.lines) == 3  # two methods and the line rho = 1
    plt.close(fig)


def test_max_stable_dt_at_another_state():
    """A compressed zero-tension state vs a stretched one: the tension adds transverse stiffness."""
    b = mslab.SceneBuilder(2)
    a = b.add_particle([0.0, 0.0], pinned=True)
    p = b.add_particle([1.0, 0.0], mass=1.0)
    b.add_spring(a, p, stiffness=100.0, rest_length=0.5)  # stretched to twice its rest length
    scene = b.build()
    # axial k = 100, transverse k (1 - L/l) = 50: w_max = 10
    assert st.max_stable_dt(scene, "verlet") == pytest.approx(0.2, rel=1e-9)
    x = scene.state0.x.copy()
    x[1] = [0.0, 0.75]  # now along y, stretched to 1.5 rest lengths
    other = mslab.State(x, scene.state0.v)
    assert st.max_stable_dt(scene, "verlet", state=other) == pytest.approx(0.2, rel=1e-9)
    K, _, _ = st.linearise(scene, other.x, other.v)
    np.testing.assert_allclose(np.sort(np.linalg.eigvalsh(-K.toarray())), [100 / 3, 100.0])


def test_amplification_is_infinite_at_a_pole_not_an_error():
    z = np.array([1.0, 0.5, -1.0, 2j])
    R = st.amplification("implicit_euler", z)
    assert np.isinf(R[0])
    np.testing.assert_allclose(R[1:], 1.0 / (1.0 - z[1:]))
    assert np.isinf(st.amplification("implicit_midpoint", np.array([2.0 + 0j]))[0])


def test_region_plot_through_a_pole():
    import matplotlib.pyplot as plt

    from mslab.plots import plot_stability_regions

    fig, ax = plt.subplots()
    plot_stability_regions(["implicit_euler"], ax=ax, re=(-3, 3), im=(-3, 3), n=241)  # grid holds z = 1
    plt.close(fig)


# -- high-degree stability polynomials: the imaginary limit isolated exactly --------------------
def _mp_imag_limit(A, b, dps: int = 60) -> float:
    """First y > 0 where |R(iy)| exceeds 1, in mpmath at ``dps`` digits from the exact tableau.

    ``R(z) = 1 + sum_k z^k b^T A^(k-1) 1`` (explicit), evaluated directly (no polynomial in
    ``y^2``, no root isolation): a scan in steps of 1e-3 for the first sign change of
    ``|R(iy)|^2 - 1``, then bisection to 1e-30.
    """
    import mpmath as mp

    with mp.workdps(dps):
        s = len(b)
        Am = mp.matrix([[mp.mpf(int(a.p)) / int(a.q) for a in row] for row in A])
        w = mp.matrix([1] * s)
        coef = [mp.mpf(1)]
        for _ in range(s):
            coef.append(sum(mp.mpf(int(bi.p)) / int(bi.q) * w[i] for i, bi in enumerate(b)))
            w = Am * w

        def excess(y):
            return abs(mp.polyval(coef[::-1], 1j * y)) ** 2 - 1

        y, step = mp.mpf(0), mp.mpf("1e-3")
        while excess(y + step) <= 0:
            y += step
        lo, hi = y, y + step
        while hi - lo > mp.mpf("1e-30"):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if excess(mid) <= 0 else (lo, mid)
        return float(lo)


@pytest.mark.parametrize("name", ["SSP104", "SSPRK3(9)", "SSPRK3(16)"])
@pytest.mark.parametrize("given", ["exact", "float"])
def test_imag_limit_of_high_degree_polynomials(name, given):
    rk = pytest.importorskip("nodepy.runge_kutta_method")
    method = {"SSP104": lambda: rk.loadRKM("SSP104"), "SSPRK3(9)": lambda: rk.SSPRK3(9),
              "SSPRK3(16)": lambda: rk.SSPRK3(16)}[name]()
    A, b = method.A.tolist(), method.b.tolist()
    truth = _mp_imag_limit(A, b)
    assert truth == pytest.approx({"SSP104": 4.921453, "SSPRK3(9)": 4.117648, "SSPRK3(16)": 5.984969}[name],
                                  abs=1e-6)  # the values of the independent check
    if given == "float":
        A, b = [[float(a) for a in row] for row in A], [float(w) for w in b]
    ours = mslab.ExplicitRK(A, b, name="ssp", order=3)
    limit = st.imag_limit(ours)
    assert abs(limit - truth) < 1e-9
    y = np.linspace(0.0, limit, 2001)
    assert np.abs(st.amplification(ours, 1j * y)).max() <= 1 + 1e-12


def test_damped_stiff_spring_gives_forward_euler_its_small_step():
    """|1 + h lam| <= 1 on lam = -g/2 +- i sqrt(k/m - g^2/4) is h <= g m / k (far below the scan)."""
    b = mslab.SceneBuilder(dim=1)
    p = b.add_particle([0.0], mass=1.0, pinned=True)
    q = b.add_particle([1.0], mass=1.0)
    b.add_spring(p, q, stiffness=1e6)
    b.add_damping(gamma=1.0)
    scene = b.build()
    gamma, k = 1.0, 1e6
    assert mslab.stability.max_stable_dt(scene, "euler") == pytest.approx(gamma / k, rel=1e-9)
    # undamped, forward Euler has no stable step at all
    b2 = mslab.SceneBuilder(dim=1)
    p = b2.add_particle([0.0], mass=1.0, pinned=True)
    q = b2.add_particle([1.0], mass=1.0)
    b2.add_spring(p, q, stiffness=1e6)
    assert mslab.stability.max_stable_dt(b2.build(), "euler") == 0.0
