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
    # the round-off floor's row sums: max_i sum_j sum_e |c M^-1 (c K_e + D_e)|_ij over the effects' terms
    minv = np.repeat(system.inv_mass, dim)
    stiff, damp = system.jacobian_terms(x, v)
    lin = sum(abs(k) * c * c for k in stiff) + sum(abs(d) * c for d in damp)
    rows = np.asarray(lin.sum(axis=1)).ravel() * minv
    assert solver.row_sum == pytest.approx(rows.max(), rel=1e-13)
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
