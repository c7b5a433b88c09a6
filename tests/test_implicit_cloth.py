"""Implicit methods at cloth scale (issue 12): kept factorisations, the indefinite fallback,
Newton's line search, Baraff-Witkin and the fast mass-spring method."""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest

import mslab
from mslab import stability
from mslab.errors import InstabilityError
from mslab.integrators import ImplicitRK
from mslab.integrators.families.local_global import LocalGlobal
from mslab.integrators.newton import factor, linear, newton_matrix
from mslab.scenes.generators import cloth
from mslab.scenes.loader import scene_path
from mslab.scenes.toml_read import read_scene_file
from mslab.scenes.validate import scene_from_doc
from mslab.state import State


def scaled_cloth(n: int, drag_rate: float = 0.0):
    """The built-in cloth with n x n particles (same 1 kg); drag ``gamma = rate * m`` or none."""
    doc = copy.deepcopy(read_scene_file(scene_path("cloth"), "cloth.toml"))
    doc["particles"]["nx"] = doc["particles"]["ny"] = n
    if drag_rate:
        doc["damping"]["gamma"] = drag_rate * doc["particles"]["total_mass"] / (n * n)
    else:
        del doc["damping"]
    return scene_from_doc(doc, "cloth.toml", default_name="cloth", overrides={})


def ie_residual(system, x0, v0, x1, v1, dt):
    """Implicit Euler's equations, written independently of the solver: max of both residuals."""
    free = ~system.pinned
    f = system.force(x1, v1)
    res_v = system.mass[free, None] * (v1[free] - v0[free]) - dt * f[free]
    res_x = x1 - x0 - dt * v1
    return max(float(np.abs(res_v).max()) / dt, float(np.abs(res_x).max()))


def run(method, scene, dt, steps):
    state, system = scene.state0, scene.system
    before = system.counters.snapshot()
    xs = []
    for _ in range(steps):
        state = method.step(system, state, dt)
        xs.append(state.x)
    return np.array(xs), system.counters.since(before)


# -- Newton with kept factorisations ------------------------------------------------------------------
@pytest.mark.parametrize("which", ["stiff_chain", "cloth"])
def test_reuse_gives_the_fresh_trajectory_with_fewer_factorisations(which):
    reuse = ImplicitRK([[1]], [1], name="ie_reuse", order=1, linear_solver="reuse")
    fresh = ImplicitRK([[1]], [1], name="ie_fresh", order=1, linear_solver="fresh")
    make = (lambda: mslab.load_scene("stiff_chain")) if which == "stiff_chain" else (lambda: scaled_cloth(12))
    dt, steps = (0.01, 40) if which == "stiff_chain" else (1 / 60, 20)
    x_r, work_r = run(reuse, make(), dt, steps)
    x_f, work_f = run(fresh, make(), dt, steps)
    # Newton stops at max|g| <= 1e-10 (1 + max|v|) on the velocity: positions agree to h times that
    assert np.abs(x_r - x_f).max() < 1e-8
    assert work_r["n_factor"] < work_f["n_factor"] / 2
    assert work_f["n_factor"] == work_f["n_solve"] == work_f["n_jac"]


def test_symmetric_factor_reads_the_inertia():
    """Symmetric-mode SuperLU's pivots count negative eigenvalues (Sylvester), checked with eigvalsh."""
    scene = scaled_cloth(10)
    s = scene.system
    x = scene.state0.x * 0.6  # every spring compressed to 60 %
    K, D = s.jacobians(x, scene.state0.v)
    free = np.repeat(~s.pinned, 3)
    A = newton_matrix.newton_matrix(K, D, np.repeat(s.mass, 3), free, 1 / 30)
    negative = int(np.count_nonzero(np.linalg.eigvalsh(A.toarray()) < 0))
    assert negative > 0
    old = factor.DENSE_MAX
    try:
        factor.DENSE_MAX = 10  # force the sparse path on this small matrix
        f = factor.Factor(A, s.counters)
    finally:
        factor.DENSE_MAX = old
    assert not f.definite and f.n_negative == negative


@pytest.mark.parametrize("policy", ["reuse", "fresh"])
def test_hard_compression_falls_back_and_converges(policy, monkeypatch):
    """The stiff chain squeezed to 80 % of its length: Newton's matrix is indefinite (checked
    with eigvalsh), the factorisation says so, and Newton still converges to implicit Euler."""
    scene = mslab.load_scene("stiff_chain")
    s = scene.system
    x0 = scene.state0.x[0] + 0.8 * (scene.state0.x - scene.state0.x[0])
    x0[:, 1] += 1e-3 * np.random.default_rng(0).standard_normal(len(x0))
    state = State(x0, np.zeros_like(x0))
    K, D = s.jacobians(x0, state.v)
    A = newton_matrix.newton_matrix(K, D, np.repeat(s.mass, 2), np.repeat(~s.pinned, 2), 0.01)
    negative = int(np.count_nonzero(np.linalg.eigvalsh(A.toarray()) < 0))
    assert negative > 0 and not linear.Factor(A, s.counters).definite
    method = ImplicitRK([[1]], [1], name="ie_" + policy, order=1, linear_solver=policy)
    shifts = []
    original = linear.StageSolver.shifted_direction

    def counted(self, r):
        shifts.append(1)
        return original(self, r)

    monkeypatch.setattr(linear.StageSolver, "shifted_direction", counted)
    before = s.counters.snapshot()
    new = method.step(s, state, 0.01)
    work = s.counters.since(before)
    assert shifts  # indefinite Newton matrices: the shifted (definite) fallback was taken
    assert work["n_factor"] > len(shifts)  # each shift is at least one more counted factorisation
    assert ie_residual(s, state.x, state.v, new.x, new.v, 0.01) < 1e-6


@pytest.mark.parametrize("dt", [1 / 30, 1 / 15])
def test_newton_converges_on_an_undamped_cloth_at_large_steps(dt):
    scene = scaled_cloth(16)
    s, state = scene.system, scene.state0
    method = mslab.get_method("implicit_euler")
    for _ in range(6):
        new = method.step(s, state, dt)
        assert ie_residual(s, state.x, state.v, new.x, new.v, dt) < 1e-6
        state = new


def test_newton_failure_is_a_clear_convergence_error():
    scene = scaled_cloth(10)
    tight = ImplicitRK([[1]], [1], name="ie_two", order=1)
    tight.max_iter = 1
    with pytest.raises(mslab.ConvergenceError, match=r"did not converge in \d+ iterations"):
        mslab.simulate(scene, tight, dt=1 / 15, t_end=2 / 15)


# -- Baraff-Witkin ------------------------------------------------------------------------------------------
def test_baraff_witkin_is_one_newton_step_of_implicit_euler():
    bw, ie = mslab.get_method("baraff_witkin"), mslab.get_method("implicit_euler")
    # linear forces (zero rest lengths): one Newton step is the solution
    lin = cloth(6, 6, gravity=9.81)
    for e in lin.system.effects:
        if e.name == "springs":
            e.rest_length[:] = 0.0
    a, b = bw.step(lin.system, lin.state0, 0.05), ie.step(lin.system, lin.state0, 0.05)
    assert np.abs(a.x - b.x).max() < 1e-10
    # rotating springs: the one-step deviation shrinks like h^2 (a local error of a first-order method)
    scene = scaled_cloth(8)
    state = mslab.get_method("implicit_euler").step(scene.system, scene.state0, 0.02)
    state = State(state.x, state.v * 5.0)
    hs = np.array([0.004, 0.002, 0.001])
    dev = [np.abs(bw.step(scene.system, state, h).x - ie.step(scene.system, state, h).x).max() for h in hs]
    assert np.polyfit(np.log(hs), np.log(dev), 1)[0] > 1.8


# -- fast mass-spring -------------------------------------------------------------------------------------
def test_fast_mass_spring_converges_to_implicit_euler():
    scene = mslab.load_scene("cloth")  # 10 x 10, drag 1/s
    s = scene.system
    state = mslab.get_method("implicit_euler").step(s, scene.state0, 1 / 30)
    ref = mslab.get_method("implicit_euler").step(s, state, 1 / 30)
    move = np.abs(ref.x - state.x).max()
    rel = [np.abs(LocalGlobal(iterations=k).step(s, state, 1 / 30).x - ref.x).max() / move
           for k in (1, 10, 100, 1000)]
    assert all(b < a for a, b in zip(rel, rel[1:], strict=False))
    assert rel[-1] < 1e-3
    many = LocalGlobal(iterations=100000, tol=1e-13).step(s, state, 1 / 30)
    assert np.abs(many.x - ref.x).max() < 1e-8
    assert ie_residual(s, state.x, state.v, many.x, many.v, 1 / 30) < 1e-6


def test_fast_mass_spring_is_implicit_euler_on_linear_springs():
    """Zero rest lengths: the local step is exact, one global solve is implicit Euler's step."""
    scene = cloth(6, 6, gamma=0.02)
    for e in scene.system.effects:
        if e.name == "springs":
            e.rest_length[:] = 0.0
    one = LocalGlobal(iterations=1).step(scene.system, scene.state0, 0.1)
    ref = mslab.get_method("implicit_euler").step(scene.system, scene.state0, 0.1)
    assert np.abs(one.x - ref.x).max() < 1e-10 and np.abs(one.v - ref.v).max() < 1e-9


def test_fast_mass_spring_is_a_stable_in_the_linear_limit():
    assert stability.real_interval("fast_mass_spring") == -np.inf
    assert stability.imag_limit("fast_mass_spring") == np.inf
    assert stability.oscillator_limit("fast_mass_spring") == np.inf
    z = -np.geomspace(1e-3, 1e6, 50)[:, None] * np.exp(1j * np.linspace(-np.pi / 2, np.pi / 2, 31))[None]
    assert np.all(np.abs(stability.amplification("fast_mass_spring", z)) <= 1.0 + 1e-12)
    for hw, hg in [(0.5, 0.0), (3.0, 0.2), (30.0, 1.0)]:
        measured = stability.measured_amplification_matrix("fast_mass_spring", hw, hg)
        assert stability.spectral_radius(measured) < 1.0


def test_fast_mass_spring_keeps_pins_and_momentum():
    scene = mslab.load_scene("cloth")
    tr = mslab.simulate(scene, "fast_mass_spring", dt=1 / 30, t_end=1.0)
    pinned = scene.system.pinned
    kept = np.broadcast_to(scene.state0.x[pinned], tr.x[:, pinned].shape)
    np.testing.assert_array_equal(tr.x[:, pinned], kept)
    free = cloth(8, 8, gravity=None, pin="none")
    rng = np.random.default_rng(3)
    state = State(free.state0.x, rng.standard_normal(free.state0.x.shape))
    m = free.system.mass[:, None]
    p0 = (m * state.v).sum(axis=0)
    fms = mslab.get_method("fast_mass_spring")
    h, n_steps = 1 / 30, 20
    for _ in range(n_steps):
        state = fms.step(free.system, state, h)
    # Error model: 1^T L = 0 (a graph Laplacian), so each global solve (M + h^2 L) x = b keeps
    # sum(M x) up to its residual, |r| <= n_dof eps sum(m |x|) for a backward-stable solve; v =
    # (x_{n+1} - x_n) / h turns that into a momentum error of n_dof eps sum(m |x|) / h per step.
    # (A method losing momentum at its truncation error, O(h^2), exceeds this by 10^8.)
    n_dof = state.x.size
    bound = n_steps * n_dof * np.finfo(float).eps * (m * np.abs(state.x)).sum() / h
    assert np.abs((m * state.v).sum(axis=0) - p0).max() < bound


def test_fast_mass_spring_is_first_order():
    from mslab import precision

    scene = mslab.scenes.chain(5, dim=2, stiffness=200.0, gravity=9.81)
    result = precision.convergence(scene, ["fast_mass_spring"], [0.02, 0.01, 0.005, 0.0025], t_end=0.5)
    assert result.orders["fast_mass_spring"] == pytest.approx(1.0, abs=0.15)


def test_fast_mass_spring_stable_where_every_explicit_method_blows_up():
    scene = mslab.load_scene("cloth")
    tr = mslab.simulate(scene, "fast_mass_spring", dt=1 / 30, t_end=2.0)
    assert np.all(np.isfinite(tr.x)) and np.abs(tr.x).max() < 3.0
    assert tr.energy.total[-1] <= tr.energy.total[0] + 1e-9  # implicit: energy only leaves
    for name in mslab.methods():
        if mslab.get_method(name).explicit:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                with pytest.raises(InstabilityError):
                    mslab.simulate(scene, name, dt=1 / 30, t_end=2.0)


def test_friction_makes_the_newton_matrix_nonsymmetric_and_lu_solves_it():
    """Friction's df/dv is not symmetric: a Cholesky of half the matrix gave wrong directions.

    The cloth falling onto a ball with friction (lesson 08) converges at dt = 10 ms with fresh
    and with kept factorisations, and the factor kind says LU.
    """
    from mslab.integrators.newton import linear, newton_matrix

    scene = mslab.load_scene("cloth_on_sphere")
    for policy in ("fresh", "reuse"):
        method = mslab.ImplicitRK([[1]], [1], name=f"ie_{policy}", order=1, linear_solver=policy)
        traj = mslab.simulate(scene, method, dt=1e-2, t_end=0.4)
        assert traj.complete and traj.stats.n_iter > traj.stats.steps
    A = newton_matrix.newton_matrix(*scene.system.jacobians(traj.x[-1], traj.v[-1]),
                             np.repeat(scene.system.mass, 3), np.repeat(~scene.system.pinned, 3), 1e-2)
    assert not newton_matrix.is_symmetric(A)
    factor = linear.Factor(A, scene.system.counters)
    assert factor.kind in ("lu", "lu_pivoted")
    b = np.random.default_rng(1).standard_normal(A.shape[0])
    assert np.linalg.norm(A @ factor.solve(b) - b) <= 1e-10 * np.linalg.norm(b)


# -- fast mass-spring: compiled iteration, Chebyshev acceleration (issue 22) ------------------------------
def test_compiled_local_step_equals_numpy():
    """The compiled pass (local step, right-hand side, update) against vectorised numpy, to 1e-12."""
    from mslab.integrators.families import local_step

    scene = scaled_cloth(9)
    s = scene.system
    springs = next(e for e in s.effects if e.name == "springs")
    rng = np.random.default_rng(5)
    x = scene.state0.x + 0.05 * rng.standard_normal(scene.state0.x.shape)
    x[7] = x[8]  # a spring of zero length: no force
    free_idx = np.flatnonzero(~s.pinned)
    extra, base = rng.standard_normal(x.shape), rng.standard_normal((free_idx.size, 3))
    for dim in (2, 3):  # the unrolled 3D loop and the general one (projections_py)
        xd, extra_d, base_d = (np.ascontiguousarray(a[:, :dim]) for a in (x, extra, base))
        jd, rhs = np.empty_like(xd), np.empty(base_d.shape, order="F")
        args = (xd, springs.i, springs.j, springs.stiffness, springs.rest_length, extra_d, base_d, 1e-3,
                free_idx)
        local_step.local_rhs(*args, jd, rhs)
        jd_ref, rhs_ref = local_step.local_rhs_numpy(*args)
        scale = np.abs(jd_ref).max()
        assert np.abs(jd - jd_ref).max() <= 1e-12 * scale
        assert np.abs(rhs - rhs_ref).max() <= 1e-12 * np.abs(rhs_ref).max()
    for chebyshev, omega, relax in [(False, 1.0, 1.0), (True, 1.0, 1.0), (True, 1.7, 1.0), (True, 1.7, 1.9)]:
        xa, prev = x.copy(), x + rng.standard_normal(x.shape)
        prev_in = prev.copy()
        change = local_step.update(xa, rhs, prev, free_idx, omega, relax, chebyshev)
        old, before = x[free_idx], prev_in[free_idx]
        want = omega * (relax * (rhs - old) + old - before) + before if chebyshev else rhs
        np.testing.assert_allclose(xa[free_idx], want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
        assert change == pytest.approx(np.abs(want - x[free_idx]).max(), rel=1e-12)
        np.testing.assert_array_equal(prev[free_idx], x[free_idx] if chebyshev else prev_in[free_idx])


def test_chebyshev_has_the_plain_fixed_point_and_converges_to_implicit_euler():
    """Wang 2015's extrapolation keeps the fixed point (implicit Euler's step), reached in fewer sweeps."""
    scene = mslab.load_scene("cloth")
    s = scene.system
    ie = mslab.get_method("implicit_euler")
    state = ie.step(s, scene.state0, 1 / 30)
    ref = ie.step(s, state, 1 / 30)
    move = np.abs(ref.x - state.x).max()
    rel = [np.abs(LocalGlobal(iterations=k, chebyshev=True).step(s, state, 1 / 30).x - ref.x).max() / move
           for k in (40, 160, 640)]
    assert all(b < a for a, b in zip(rel, rel[1:], strict=False)) and rel[-1] < 1e-8
    plain40 = LocalGlobal(iterations=40).step(s, state, 1 / 30)
    assert rel[0] < 0.5 * np.abs(plain40.x - ref.x).max() / move
    runs = {}
    for chebyshev in (False, True):
        before = s.counters.snapshot()
        new = LocalGlobal(iterations=100000, tol=1e-13, chebyshev=chebyshev).step(s, state, 1 / 30)
        runs[chebyshev] = new, s.counters.since(before)["n_iter"]
    assert np.abs(runs[True][0].x - runs[False][0].x).max() < 1e-8
    assert ie_residual(s, state.x, state.v, runs[True][0].x, runs[True][0].v, 1 / 30) < 1e-6
    assert runs[True][1] < runs[False][1] / 3


def test_chebyshev_counts_its_setup_and_keeps_the_contract():
    """Counters exact (the spectral radius estimate once per system and dt), pins still, momentum,
    a fully pinned scene still."""
    from mslab.integrators.families.local_global import POWER_ITERATIONS

    scene = mslab.load_scene("cloth")
    s = scene.system
    method = LocalGlobal(iterations=10, chebyshev=True)
    work = []
    state = scene.state0
    for _ in range(3):
        before = s.counters.snapshot()
        state = method.step(s, state, 1 / 30)
        work.append(s.counters.since(before))
    assert work[0]["n_factor"] == 1 and work[1]["n_factor"] == work[2]["n_factor"] == 0
    assert work[0]["n_solve"] == 10 + POWER_ITERATIONS and work[0]["n_force"] == 11 + POWER_ITERATIONS
    assert work[1] == work[2] and work[1]["n_solve"] == work[1]["n_force"] == work[1]["n_iter"] == 10
    # start() does the setup before the first frame (as simulate calls it): counted there, not in the frame
    fresh = mslab.load_scene("cloth")
    before = fresh.system.counters.snapshot()
    method.start(fresh.system, fresh.state0, 1 / 30)
    setup = fresh.system.counters.since(before)
    assert setup["n_factor"] == 1 and setup["n_solve"] == POWER_ITERATIONS
    before = fresh.system.counters.snapshot()
    method.step(fresh.system, fresh.state0, 1 / 30)
    assert fresh.system.counters.since(before) == work[1]
    pinned = s.pinned
    np.testing.assert_array_equal(state.x[pinned], scene.state0.x[pinned])
    free = cloth(8, 8, gravity=None, pin="none")
    rng = np.random.default_rng(3)
    state = State(free.state0.x, rng.standard_normal(free.state0.x.shape))
    m = free.system.mass[:, None]
    p0 = (m * state.v).sum(axis=0)
    h, n_steps = 1 / 30, 20
    for _ in range(n_steps):
        state = method.step(free.system, state, h)
    # Error model as for the plain method; each extrapolation omega (relax (new - x) + x - prev) + prev
    # combines three iterates with weights summing to 1 (momentum kept exactly) and absolute sum
    # <= 7 (omega, relax <= 2): at most 7 more roundings of |x| per coordinate and iteration
    n_dof = state.x.size
    bound = 8 * n_steps * n_dof * np.finfo(float).eps * (m * np.abs(state.x)).sum() / h
    assert np.abs((m * state.v).sum(axis=0) - p0).max() < bound
    from mslab.system import System

    small = cloth(4, 4).system
    still = System(small.mass, np.ones(small.n_particles, dtype=bool), small.effects, 3)
    x0 = cloth(4, 4).state0.x
    out = method.step(still, State(x0, np.zeros_like(x0)), h)
    np.testing.assert_array_equal(out.x, x0)
    np.testing.assert_array_equal(out.v, 0.0)
