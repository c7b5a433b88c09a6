"""Implicit Euler through a float32 supernodal Cholesky (issue 38, item 4).

Truths: the Newton matrix itself (``L L^T`` rebuilt densely), scipy's ``spsolve`` and the float64
factorisation on the same matrix, implicit Euler's equations written out, and the float64
path's trajectory.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from test_implicit_cloth import ie_residual, scaled_cloth

from mslab.integrators import ImplicitRK
from mslab.integrators.newton import linear, mixed
from mslab.integrators.newton.factor import Factor
from mslab.integrators.newton.pcg import pcg
from mslab.system import Counters

DT = 1 / 60


@pytest.fixture(autouse=True)
def small_mixed(monkeypatch):
    """The float32 path on small cloths too (by default it starts at MIXED_MIN unknowns)."""
    monkeypatch.setattr(linear, "MIXED_MIN", linear.DENSE_MAX)


def newton_matrix(n: int = 14, steps: int = 1):
    """A cloth's Newton matrix (free dofs, on its kept pattern) after ``steps`` implicit Euler steps."""
    scene = scaled_cloth(n, drag_rate=1.0)
    system, state = scene.system, scene.state0
    ie = ImplicitRK([[1]], [1], name="ie_double", order=1, factor_precision="double")
    for _ in range(steps):
        state = ie.step(system, state, DT)
    solver = linear.StageSolver(system, DT, "reuse", precision="mixed")
    A = solver._assemble((state.x + DT * state.v, state.v), None)
    return solver, A


def dense_factor(f: mixed.MixedFactor) -> np.ndarray:
    """The float32 factor as a dense lower triangular matrix (read from the supernodes)."""
    a = f.analysis
    n = a.perm.size
    L = np.zeros((n, n))
    for first, k, m, start, r0 in a.sn:
        rows = np.concatenate([np.arange(first, first + k), a.rows[r0:r0 + m - k]])
        block = f.L[start:start + m * k].reshape(k, m).T  # column-major m x k
        for j in range(k):
            L[rows[j:], first + j] = block[j:, j]
    return L


def test_the_float32_factor_is_a_cholesky_factor_of_the_permuted_matrix():
    solver, A = newton_matrix()
    assert A.shape[0] > linear.DENSE_MAX
    f = mixed.mixed_factor(A, Counters(), solver.pattern, dim=3)
    assert f is not None and f.analysis.sn[:, 1].max() > 3  # supernodes wider than one particle
    L = dense_factor(f)
    P = A.toarray()[np.ix_(f.analysis.perm, f.analysis.perm)] * f.scale
    assert np.all(np.diag(L) > 0)
    assert np.abs(L @ L.T - P).max() <= 1e-6 * np.abs(P).max()  # float32 rounding, not worse
    assert np.abs(L @ L.T - P).max() > 0.0  # really float32 (float64 would give ~1e-16)


def test_cg_with_the_float32_factor_solves_the_float64_system():
    solver, A = newton_matrix()
    f = mixed.mixed_factor(A, Counters(), solver.pattern, dim=3)
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    one = f.solve(b)
    assert np.linalg.norm(A @ one - b) <= 1e-4 * np.linalg.norm(b)  # one application: a few decades
    x, its, ratio = pcg(A, b, f, 1e-12, 10)
    assert x is not None and its <= 4 and ratio <= 1e-12
    exact = spla.spsolve(A.tocsc(), b)
    double = Factor(A, Counters(), pattern=solver.pattern, symmetric=True)
    assert double.kind == "cholmod"
    assert np.abs(x - exact).max() <= 1e-10 * np.abs(exact).max()
    assert np.abs(x - double.solve(b)).max() <= 1e-10 * np.abs(exact).max()


def test_the_blocked_float32_solve_is_within_its_rounding_error_model():
    """``solve`` against the exact ``P^T L^-T L^-1 P b`` of the same float32 factor (dense, float64).

    Float32 triangular solves (any order of the sums, BLAS or loops) are backward stable
    (Higham, Accuracy and Stability, Thm 8.5): ``(L + dL) z = b~`` with ``|dL| <= gamma_k |L|``,
    ``gamma_k = k u / (1 - k u)``, ``u = 2^-24``, ``k`` the terms of a row plus one (the scatter
    of a supernode's sums); ``b~`` is ``b`` rounded to float32 (``|b~ - b| <= u |b|``). To first
    order (factor 2 for the second) the error of ``y = L^-T L^-1 b`` is at most
    ``|L^-T| (|L^-1| (u |b| + gamma_k |L| |z|) + gamma_k |L^T| |y|)`` componentwise.
    """
    from scipy.linalg import solve_triangular

    solver, A = newton_matrix()
    f = mixed.mixed_factor(A, Counters(), solver.pattern, dim=3)
    L, perm = dense_factor(f), f.analysis.perm
    b = np.random.default_rng(6).standard_normal(A.shape[0]) * np.exp(np.linspace(-3, 3, A.shape[0]))
    z = solve_triangular(L, b[perm], lower=True)
    y = solve_triangular(L.T, z, lower=False)
    exact = np.empty_like(y)
    exact[perm] = y * f.scale
    u = 2.0 ** -24
    k = int(np.count_nonzero(L, axis=1).max()) + 1
    gamma = k * u / (1 - k * u)
    inv = np.abs(solve_triangular(L, np.eye(L.shape[0]), lower=True))
    bound = np.empty_like(y)
    bound[perm] = 2 * f.scale * inv.T @ (inv @ (u * np.abs(b[perm]) + gamma * np.abs(L) @ np.abs(z))
                                         + gamma * np.abs(L.T) @ np.abs(y))
    x = f.solve(b)
    assert np.all(np.abs(x - exact) <= bound)
    assert bound.max() <= 1e-3 * np.abs(exact).max()  # a bound that says something
    assert np.abs(x - exact).max() > 1e-10 * np.abs(exact).max()  # float32 arithmetic, not float64's 1e-16
    # b is scaled by a power of two before float32: the same bits for 2^120 b and 2^-140 b
    assert np.array_equal(f.solve(b * 2.0 ** 120), x * 2.0 ** 120)
    assert np.array_equal(f.solve(b * 2.0 ** -140), x * 2.0 ** -140)
    assert np.array_equal(f.solve(np.zeros_like(b)), np.zeros_like(b))


def test_a_matrix_that_is_not_positive_definite_gives_no_float32_factor():
    solver, A = newton_matrix()
    # dense: 582 x 582 costs 0.05 s, ARPACK's shift-invert around 0 took 6-14 s for the same number
    lowest = np.linalg.eigvalsh(A.toarray())[0]
    assert lowest > 0
    shifted = (A - 2 * lowest * sp.identity(A.shape[0])).tocsr()
    assert mixed.mixed_factor(shifted, Counters(), None, dim=3) is None
    assert mixed.mixed_factor(A, Counters(), None, dim=3) is not None


@pytest.mark.parametrize("failure", [None, "not_definite", "cg_stalls"])
def test_the_float64_factor_takes_over_when_float32_fails(monkeypatch, failure):
    """The float32 factor where it works; CHOLMOD's when it fails or CG with it stalls."""
    solver, A = newton_matrix()
    if failure == "not_definite":
        monkeypatch.setattr(mixed, "mixed_factor", lambda *args, **kwargs: None)
    elif failure == "cg_stalls":  # a useless preconditioner: CG cannot reach its tolerance in time
        monkeypatch.setattr(mixed.MixedFactor, "solve", lambda self, b: np.asarray(b, dtype=float).copy())
    monkeypatch.setattr(solver, "_assemble", lambda point, r: A)
    mixed.analysis_of(solver.pattern, A, 3)  # a pattern met before
    r = np.random.default_rng(4).standard_normal(solver.free.size)
    du = solver.direction(None, r, exact=True)
    assert solver.factor.kind == ("mixed32" if failure is None else "cholmod")
    exact = spla.spsolve(A.tocsc(), solver.rhs(r))
    assert np.abs(du[solver.free] - exact).max() <= 1e-10 * np.abs(exact).max()


def trajectory(precision: str, steps: int = 6, n: int = 14) -> tuple:
    """Implicit Euler from rest: the system, the states, the kinds of the kept factors at the end.

    Six steps: float32 factors are kept long (``MIXED_FACTOR_OVER_SOLVE``), the first float32
    factorisation on this cloth comes at the fifth step.
    """
    scene = scaled_cloth(n, drag_rate=1.0)
    system, state = scene.system, scene.state0
    ie = ImplicitRK([[1]], [1], name=f"ie_{precision}", order=1, factor_precision=precision)
    states = [state]
    for _ in range(steps):
        states.append(ie.step(system, states[-1], DT))
    kinds = {s.factor.kind for s in linear._CACHE[system].values() if s.factor is not None}
    return system, states, kinds


def test_a_pattern_met_once_is_factored_in_float64(monkeypatch):
    """The float32 analysis is made for a pattern factored a second time, not for one met once."""
    solver, A = newton_matrix()
    monkeypatch.setattr(solver, "_assemble", lambda point, r: A)
    r = np.random.default_rng(5).standard_normal(solver.free.size)
    solver.direction(None, r, exact=True)
    assert solver.factor.kind == "cholmod" and getattr(solver.pattern, "mixed", None) is None
    solver.factor = None  # (no kept factors: the next direction factors afresh)
    solver.direction(None, r, exact=True)
    assert solver.factor.kind == "mixed32"


def test_newton_finds_the_same_root_with_mixed_and_double_factors():
    system, mixed_states, kinds = trajectory("mixed")
    assert kinds == {"mixed32"}
    _, double_states, double_kinds = trajectory("double")
    assert double_kinds == {"cholmod"}
    for k in range(1, len(mixed_states)):
        before, a, b = double_states[k - 1], mixed_states[k], double_states[k]
        step = np.abs(b.x - before.x).max()
        assert np.abs(a.x - b.x).max() <= 1e-10 * step  # the same root to Newton's tolerance
        # and it is implicit Euler's step from the same state (the equations written out)
        one = ImplicitRK([[1]], [1], name="ie_mixed", order=1).step(system, before, DT)
        assert ie_residual(system, before.x, before.v, one.x, one.v, DT) <= 1e-8


def test_float32_factors_are_kept_twice_as_long_as_float64_ones():
    """A float32 factorisation is counted as forty of its solves (``MIXED_FACTOR_OVER_SOLVE``).

    So the stage solver runs conjugate gradients on kept float32 factors where the float64 path
    factors afresh: at most half the factorisations on the same run (on this 14 x 14 cloth 2
    against 6 in 6 steps; 6 against 6 with the ratio of six used before the blocked solves),
    the same roots.
    """
    system, mixed_states, _ = trajectory("mixed", steps=6)
    double_system, double_states, _ = trajectory("double", steps=6)
    assert 2 * system.counters.n_factor <= double_system.counters.n_factor
    for k in range(1, len(mixed_states)):
        step = np.abs(double_states[k].x - double_states[k - 1].x).max()
        assert np.abs(mixed_states[k].x - double_states[k].x).max() <= 1e-10 * step


def test_same_bits_on_reruns_and_thread_counts():
    from threadpoolctl import threadpool_limits

    from mslab.jit import threads

    with threads(1), threadpool_limits(1, user_api="blas"):
        one = trajectory("mixed")[1]
    with threads(2), threadpool_limits(2, user_api="blas"):
        two = trajectory("mixed")[1]
    again = trajectory("mixed")[1]
    for a, b, c in zip(one, two, again, strict=True):
        assert np.array_equal(a.x, b.x) and np.array_equal(a.v, b.v)
        assert np.array_equal(a.x, c.x) and np.array_equal(a.v, c.v)


def test_below_mixed_min_the_float64_path_runs_unchanged(monkeypatch):
    monkeypatch.setattr(linear, "MIXED_MIN", 10_000)
    _, states, kinds = trajectory("mixed")
    _, double_states, _ = trajectory("double")
    assert kinds == {"cholmod"}
    for a, b in zip(states, double_states, strict=True):
        assert np.array_equal(a.x, b.x)


def test_factor_precision_is_validated():
    with pytest.raises(ValueError, match="factor_precision"):
        ImplicitRK([[1]], [1], name="bad", order=1, factor_precision="single")
