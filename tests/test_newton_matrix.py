"""Newton's matrix on a kept pattern, CHOLMOD's kept symbolic analysis, and the compiled Newton path.

References are independent of the code under test: scipy's own sparse arithmetic
(``linear.newton_matrix``, written with scipy operators), dense linear algebra, the numpy
Jacobians of the effects (themselves checked against finite differences in test_effects),
and the numpy backend of the same runs.
"""

from __future__ import annotations

import numpy as np
import pytest

import mslab
from mslab.effects.springs import Springs
from mslab.fast.model import ForceModel
from mslab.fast.newton import CompiledSystem
from mslab.integrators.newton import linear, newton_matrix
from mslab.integrators.newton.newton_matrix import FreePattern, cholmod_module
from mslab.scenes.generators import chain, cloth


def moved_cloth(n=9, drag=0.3, damping=0.0, seed=0):
    """A cloth (structural, shear, bend, drag, two pins) moved off its rest state.

    Damping along the springs makes ``df/dx`` nonsymmetric (its ``u (P_u dv)^T`` term).
    """
    scene = cloth(n, n, structural=400.0, shear=40.0, bend=4.0, damping=damping, gamma=drag)
    rng = np.random.default_rng(seed)
    x = scene.state0.x + 0.02 * rng.standard_normal(scene.state0.x.shape)
    v = rng.standard_normal(x.shape)
    return scene, x, v


def off_mass_row_sum(A, system):
    """``max_i m_i^-1 sum_j |A_ij - M_ij|`` on the free dofs, by scipy arithmetic."""
    import scipy.sparse as sp

    free = np.repeat(~system.pinned, system.dim)
    mass = np.repeat(system.mass, system.dim)[free]
    return float((np.asarray(abs(A - sp.diags(mass)).sum(axis=1)).ravel() / mass).max())


@pytest.mark.parametrize("c", [1e-3, 1 / 60, 0.1])
@pytest.mark.parametrize("damping", [0.0, 0.5])
def test_pattern_assembly_equals_scipy_arithmetic(c, damping):
    scene, x, v = moved_cloth(damping=damping)
    system = scene.system
    dim = system.dim
    free = np.repeat(~system.pinned, dim)
    solver = linear.StageSolver(system, c, "reuse")
    A = solver._assemble((x, v), np.zeros(x.size))
    K, D = system.jacobians(x, v)
    ref = newton_matrix.newton_matrix(K, D, np.repeat(system.mass, dim), free, c)
    assert A.shape == ref.shape
    assert abs(A - ref).max() <= 1e-14 * abs(ref).max()
    # the round-off floor's row sums: max_i m_i^-1 sum_j |A - M|_ij
    assert solver.row_sum == pytest.approx(off_mass_row_sum(ref, system), rel=1e-13)
    # the same pattern is kept (no new analysis) for another state, and still assembles right
    pattern = solver.pattern
    A2 = solver._assemble((x + 0.01, -v), np.zeros(x.size))
    assert solver.pattern is pattern
    ref2 = newton_matrix.newton_matrix(*system.jacobians(x + 0.01, -v), np.repeat(system.mass, dim), free, c)
    assert abs(A2 - ref2).max() <= 1e-14 * abs(ref2).max()


def test_pattern_symmetry_and_transpose():
    scene, x, v = moved_cloth()
    system = scene.system
    parts = [m for pair in system.jacobian_terms(x, v) for m in pair]
    pattern = FreePattern(parts, np.repeat(~system.pinned, system.dim))
    A = pattern.assemble(np.concatenate([p.data for p in parts]), np.ones(pattern.size))
    assert pattern.structurally_symmetric and pattern.symmetric(A.data)
    damped = moved_cloth(damping=0.5)[0].system
    parts_d = [m for pair in damped.jacobian_terms(x, v) for m in pair]
    pattern_d = FreePattern(parts_d, np.repeat(~damped.pinned, damped.dim))
    A_d = pattern_d.assemble(np.concatenate([p.data for p in parts_d]), np.ones(pattern_d.size))
    assert not pattern.matches(parts_d) and not pattern_d.symmetric(A_d.data)
    assert abs(A_d - A_d.T).max() > 1e-6 * abs(A_d).max()  # scipy agrees
    assert np.array_equal(A.data[pattern.transpose], A.T.tocsr().data)
    skew = A.data.copy()
    skew[pattern.lower[5]] += 1e-6 * abs(skew).max()
    assert not pattern.symmetric(skew)


@pytest.mark.skipif(cholmod_module() is None, reason="cvxopt (CHOLMOD) is not installed")
def test_kept_symbolic_analysis_solves_each_new_matrix_and_refuses_stale_factors():
    scene, x, v = moved_cloth(n=12)
    system = scene.system
    solver = linear.StageSolver(system, 1e-3, "reuse")  # A near M: positive definite
    rng = np.random.default_rng(2)
    factors = []
    for k in range(3):
        A = solver._assemble((x + 0.01 * k, v), np.zeros(x.size))
        f = linear.Factor(A, system.counters, pattern=solver.pattern)
        assert f.kind == "cholmod"
        b = rng.standard_normal(A.shape[0])
        assert np.allclose(f.solve(b), np.linalg.solve(A.toarray(), b), rtol=1e-10, atol=1e-12)
        factors.append(f)
    assert solver.pattern._symbolic is factors[-1]._chol  # one CHOLMOD object, refactored
    with pytest.raises(RuntimeError, match="overwritten"):
        factors[0].solve(np.ones(factors[0].A.shape[0]))


@pytest.mark.skipif(cholmod_module() is None, reason="cvxopt (CHOLMOD) is not installed")
def test_an_indefinite_matrix_on_a_kept_pattern_leaves_it_usable():
    scene, x, v = moved_cloth(n=12)
    system = scene.system
    solver = linear.StageSolver(system, 1e-3, "reuse")
    A = solver._assemble((x, v), np.zeros(x.size))
    bad = A.data.copy()
    bad[solver.pattern.diagonal[7]] = -1e3  # a negative pivot
    f = linear.Factor(solver.pattern.matrix(bad), system.counters, definite_only=True, pattern=solver.pattern)
    assert f.kind == "none" and not f.definite
    good = linear.Factor(A, system.counters, pattern=solver.pattern)
    b = np.ones(A.shape[0])
    assert np.allclose(A @ good.solve(b), b, rtol=1e-10)


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("damped", [True, False])
def test_compiled_spring_jacobians_equal_numpy(dim, damped):
    rng = np.random.default_rng(dim)
    n, m = 10, 40
    i = rng.integers(0, n, m)
    j = (i + rng.integers(1, n, m)) % n
    springs = Springs(np.stack([i, j], 1), rng.uniform(1, 100, m), rng.uniform(0.1, 2, m),
                      rng.uniform(0, 3, m) if damped else np.zeros(m), n)
    x, v = rng.normal(size=(n, dim)), rng.normal(size=(n, dim))
    x[j[0]] = x[i[0]]  # a spring of zero length: -k I, no NaN
    K, D = springs.jacobians(x, v)
    Kc, Dc = springs.compiled_jacobians(x, v)
    assert np.all(np.isfinite(Kc.data))
    assert abs(K - Kc).max() <= 1e-13 * abs(K).max()
    assert (D is None) == (Dc is None) == (not damped)
    if damped:
        assert abs(D - Dc).max() <= 1e-13 * abs(D).max()


def test_compiled_view_shares_the_system_and_counts():
    scene, x, v = moved_cloth()
    system = scene.system
    view = CompiledSystem(system, ForceModel(system))
    assert view.counters is system.counters and view.effects is system.effects
    before = system.counters.snapshot()
    a, p = view.rhs(x, v)
    a_ref, p_ref = system.rhs(x, v)
    assert np.allclose(a, a_ref, rtol=1e-13, atol=1e-12) and p == pytest.approx(p_ref, rel=1e-13)
    view.jacobians(x, v)
    assert system.counters.since(before) == {**{k: 0 for k in before}, "n_force": 2, "n_jac": 1}


@pytest.mark.parametrize("method", ["implicit_euler", "sdirk2"])
def test_sparse_cloth_steps_the_same_on_both_backends(method, monkeypatch):
    """A cloth above the dense size (CHOLMOD, kept factors, CG): compiled = numpy, same counters."""
    scene = cloth(14, 14, structural=2000.0, shear=200.0, bend=20.0, damping=0.5, gamma=0.05)
    assert 3 * scene.system.n_particles > linear.DENSE_MAX
    compiled_calls = []
    real = CompiledSystem.rhs

    def counted(self, x, v):
        compiled_calls.append(1)
        return real(self, x, v)

    monkeypatch.setattr(CompiledSystem, "rhs", counted)
    a = mslab.simulate(scene, method, dt=1 / 60, t_end=0.25, backend="numpy")
    assert not compiled_calls
    b = mslab.simulate(scene, method, dt=1 / 60, t_end=0.25, backend="numba")
    assert len(compiled_calls) == b.stats.n_force  # every evaluation of the numba run was compiled
    assert np.abs(a.x - b.x).max() <= 1e-12 * max(1.0, np.abs(a.x).max())
    sa, sb = a.stats.as_dict(), b.stats.as_dict()
    sa.pop("wall_time"), sb.pop("wall_time")
    assert sa == sb and sa["n_factor"] < sa["n_iter"]


def test_work_precision_times_on_the_requested_backend(monkeypatch):
    """``work_precision(..., backend=...)`` hands the backend to every run (lesson 07 relies on it)."""
    import importlib

    from mslab.precision import work_precision

    simulate_module = importlib.import_module("mslab.simulate")  # the module, not the function

    seen = []
    real = simulate_module.simulate

    def spy(*args, **kwargs):
        seen.append(kwargs.get("backend"))
        return real(*args, **kwargs)

    monkeypatch.setattr(simulate_module, "simulate", spy)
    scene = chain(n=4, dim=2)
    records = work_precision(scene, ["rk4"], [0.01], 0.1, repeats=1, budget=0.0, backend="numba")
    assert records[0]["ok"] and np.isfinite(records[0]["wall_time"])
    assert seen and set(seen) == {"numba"}  # error and timed runs on the backend asked for


def test_compiled_spring_jacobians_equal_finite_differences_of_the_compiled_forces():
    """An independent check: central differences of the compiled force kernel, column by column."""
    rng = np.random.default_rng(7)
    n, m, dim = 6, 12, 3
    i = rng.integers(0, n, m)
    j = (i + rng.integers(1, n, m)) % n
    springs = Springs(np.stack([i, j], 1), rng.uniform(1, 10, m), rng.uniform(0.5, 1.5, m),
                      rng.uniform(0.1, 1.0, m), n)
    system = mslab.System(np.ones(n), np.zeros(n, dtype=bool), [springs], dim)
    model = ForceModel(system)
    x, v = rng.normal(size=(n, dim)), rng.normal(size=(n, dim))
    K, D = (M.toarray() for M in springs.compiled_jacobians(x, v))
    h = 1e-6
    for col in range(n * dim):
        e = np.zeros(n * dim)
        e[col] = h
        e = e.reshape(n, dim)
        dfdx = (model.force(x + e, v)[0] - model.force(x - e, v)[0]).ravel() / (2 * h)
        dfdv = (model.force(x, v + e)[0] - model.force(x, v - e)[0]).ravel() / (2 * h)
        assert np.allclose(K[:, col], dfdx, rtol=1e-6, atol=1e-6)
        assert np.allclose(D[:, col], dfdv, rtol=1e-6, atol=1e-6)


# -- the compiled assembly, the clamped Newton matrix, the CG model (issue 22, item 2) ---------------
@pytest.mark.parametrize("damping", [0.0, 0.5])
@pytest.mark.parametrize("c", [1 / 60, 0.1])
def test_compiled_assembly_equals_the_numpy_assembly(c, damping):
    """Springs written straight into A by the compiled loop (damped springs: their compiled
    Jacobians through the generic path) = scipy's arithmetic on the numpy Jacobians."""
    scene, x, v = moved_cloth(damping=damping)
    system = scene.system
    dim = system.dim
    free = np.repeat(~system.pinned, dim)
    view = CompiledSystem(system, ForceModel(system))
    solver = linear.StageSolver(view, c, "reuse")
    assert solver.compiled is not None
    before = system.counters.snapshot()
    A = solver._assemble((x, v), np.zeros(x.size))
    assert system.counters.since(before)["n_jac"] == 1
    ref = newton_matrix.newton_matrix(*system.jacobians(x, v), np.repeat(system.mass, dim), free, c)
    assert abs(A - ref).max() <= 1e-13 * abs(ref).max()
    assert solver.row_sum == pytest.approx(off_mass_row_sum(ref, system), rel=1e-12)
    assert solver.symmetric == (damping == 0.0 or None)
    A2 = solver._assemble((x + 0.01, -v), np.zeros(x.size))  # same kept pattern, another state
    ref2 = newton_matrix.newton_matrix(*system.jacobians(x + 0.01, -v), np.repeat(system.mass, dim), free, c)
    assert abs(A2 - ref2).max() <= 1e-13 * abs(ref2).max()
    assert view.potential_energy(x) == pytest.approx(system.potential_energy(x), rel=1e-12)


def test_clamped_matrix_drops_exactly_the_compressed_springs_terms():
    """Clamped minus exact = the compressed springs' ``c^2 k (1 - L/l) P`` blocks (from the numpy
    Jacobians of a scene holding only those springs), and positive definite where exact is not."""
    scene = cloth(8, 8, structural=400.0, shear=40.0, bend=4.0, gamma=0.0)
    system = scene.system
    rng = np.random.default_rng(3)
    x = 0.7 * scene.state0.x + 0.01 * rng.standard_normal(scene.state0.x.shape)  # compressed
    v = np.zeros_like(x)
    c = 1 / 30
    free = np.repeat(~system.pinned, 3)
    view = CompiledSystem(system, ForceModel(system))
    exact = linear.StageSolver(view, c, "reuse")._assemble((x, v), v.ravel()).toarray()
    clamped = linear.StageSolver(view, c, "reuse", clamp=True)._assemble((x, v), v.ravel()).toarray()
    assert np.linalg.eigvalsh(exact).min() < 0 < np.linalg.eigvalsh(clamped).min()
    # the dropped terms: K(L) - K(L = l) of the compressed springs is k (1 - L/l) P per block
    diff = np.zeros_like(exact)
    for e in system.effects:
        s = e.hooke_springs()
        if s is None:
            continue
        length = np.linalg.norm(x[s.i] - x[s.j], axis=1)
        short = length < s.rest_length
        pairs = np.stack([s.i[short], s.j[short]], 1)
        with_rest = Springs(pairs, s.stiffness[short], s.rest_length[short], 0.0, system.n_particles)
        at_length = Springs(pairs, s.stiffness[short], length[short], 0.0, system.n_particles)
        dK = (with_rest.jacobians(x, v)[0] - at_length.jacobians(x, v)[0]).toarray()
        diff += c * c * dK[free][:, free]
    assert np.abs(clamped - exact - diff).max() <= 1e-12 * np.abs(exact).max()


def test_clamped_newton_converges_to_the_exact_step_on_a_buckling_cloth():
    """The flat sheet's first steps at dt = 1/30 buckle (compressed springs, indefinite A):
    the clamped matrix needs no shift and reaches implicit Euler's solution."""
    scene = cloth(14, 14, structural=500.0, shear=50.0, bend=5.0, gamma=0.01)
    system, state = scene.system, scene.state0
    view = CompiledSystem(system, ForceModel(system))
    exact = mslab.get_method("implicit_euler")
    clamped = mslab.ImplicitRK([[1]], [1], name="implicit_euler_clamped", order=1, newton_hessian="clamped")
    shifts = []
    real = linear.StageSolver.shifted_direction

    def counted(self, r):
        if self.compiled is not None and self.compiled.clamp:
            shifts.append(1)
        return real(self, r)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(linear.StageSolver, "shifted_direction", counted)
        for _ in range(4):
            a = exact.step(view, state, 1 / 30)
            b = clamped.step(view, state, 1 / 30)
            assert np.abs(a.x - b.x).max() < 1e-9
            state = a
    assert not shifts
    with pytest.raises(ValueError, match="backend='numba'"):
        clamped.step(system, state, 1 / 30)  # numpy evaluations: no compiled assembly
    with pytest.raises(ValueError, match="newton_hessian must be"):
        mslab.ImplicitRK([[1]], [1], newton_hessian="clampd")


def test_compiled_implicit_euler_equals_a_textbook_newton():
    """A sparse cloth (CHOLMOD, kept factors, CG by the model) against Newton written here:
    full matrix ``I - h M^-1 (h K + D)``, a dense solve every iteration, same tolerance."""
    scene = cloth(12, 12, structural=500.0, shear=50.0, bend=5.0, gamma=0.01)
    system, state, dt = scene.system, scene.state0, 1 / 60
    assert 3 * system.n_particles > linear.DENSE_MAX
    view = CompiledSystem(system, ForceModel(system))
    method = mslab.get_method("implicit_euler")
    minv = np.repeat(system.inv_mass, 3)
    for _ in range(6):
        v = state.v.copy()
        for _ in range(30):
            x = state.x + dt * v
            g = v - state.v - dt * system.acceleration(x, v)
            if np.abs(g).max() <= 1e-10 * (1 + np.abs(state.v).max()):
                break
            K, D = (M.toarray() for M in system.jacobians(x, v))
            J = np.eye(x.size) - dt * minv[:, None] * (dt * K + D)
            v = v + np.linalg.solve(J, -g.ravel()).reshape(v.shape)
        new = method.step(view, state, dt)
        assert np.abs(new.x - (state.x + dt * v)).max() < 1e-9
        state = new


def test_cg_model_refit_predicts_the_measured_rate():
    """After a refit to a rate q at a change e, the model predicts log(rtol) / log(q) iterations
    at e (the inverse of the rate formula), fewer at a smaller change, more at a larger one."""
    scene = cloth(8, 8)
    solver = linear.StageSolver(scene.system, 0.01, "reuse")
    for rate in (0.1, 0.5, 0.65):
        solver.refit(1e-3, rate)
        expected = np.log(1e-3) / np.log(rate)
        assert solver.predicted_cg_iterations(1e-3, 1e-3) == pytest.approx(expected, rel=1e-9)
        assert solver.predicted_cg_iterations(1e-4, 1e-3) < solver.predicted_cg_iterations(1e-3, 1e-3) \
            < solver.predicted_cg_iterations(1e-2, 1e-3)
