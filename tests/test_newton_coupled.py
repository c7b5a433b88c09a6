"""Newton's matrix of a fully implicit tableau (gauss2, radau_iia2), dense and sparse.

``mslab.integrators.newton.coupled`` assembles ``S`` (Newton's matrix is ``I - S``) as dense
arrays up to ``DENSE_MAX`` unknowns and in scipy.sparse above. References: the sparse
assembly (bitwise, for two stages: the same operations), and finite differences of the
stage residual ``G(U) = V - v - h A a(x + h A V, V)`` written out here from the tableau's
definition (independent of the code under test).
"""

from __future__ import annotations

import numpy as np
import pytest

import mslab
from mslab.integrators.newton import coupled
from mslab.scenes.generators import chain


def moved(scene, seed=0, spread=0.02):
    rng = np.random.default_rng(seed)
    x = scene.state0.x + spread * rng.standard_normal(scene.state0.x.shape)
    return x, rng.standard_normal(x.shape)


SCENES = {
    # pinned end, springs with damping along them, drag: D = df/dv present, K nonsymmetric
    "damped_chain": lambda: chain(6, dim=3, stiffness=200.0, damping=0.4, gamma=0.1),
    # friction and penalty contact (a kinked force; D nonsymmetric)
    "cloth_on_sphere": lambda: mslab.load_scene("cloth_on_sphere"),
    "pendulum": lambda: mslab.load_scene("pendulum"),  # no velocity dependence: D is None
}


def stage_points(system, A, x, v, dt, seed=1):
    s = A.shape[0]
    V = v[None] + 0.1 * np.random.default_rng(seed).standard_normal((s,) + v.shape)
    X = x[None] + dt * np.einsum("ij,jnd->ind", A, V)
    return X, V


@pytest.mark.parametrize("method", ["gauss2", "radau_iia2"])
@pytest.mark.parametrize("name", list(SCENES))
def test_dense_matrix_is_the_sparse_one_bitwise(name, method):
    scene = SCENES[name]()
    system = scene.system
    A = mslab.get_method(method).A
    x, v = moved(scene)
    X, V = stage_points(system, A, x, v, dt=0.01)
    dense = coupled._dense_coupling(system, A, X, V, 0.01)
    sparse = coupled._sparse_coupling(system, A, X, V, 0.01).toarray()
    assert dense.shape == sparse.shape == (A.shape[0] * x.size,) * 2
    assert np.count_nonzero(dense) > 0
    assert np.array_equal(dense, sparse)


def residual(system, A, x, v, dt, U):
    """The stages' residual ``G(U)``, from the definition of an implicit Runge-Kutta step."""
    s = A.shape[0]
    V = U.reshape((s,) + v.shape)
    X = x[None] + dt * np.einsum("ij,jnd->ind", A, V)
    a = np.stack([system.rhs(X[i], V[i])[0] for i in range(s)])
    return (V - v[None] - dt * np.einsum("ij,jnd->ind", A, a)).ravel()


@pytest.mark.parametrize("method", ["gauss2", "radau_iia2"])
def test_newton_matrix_is_the_residuals_jacobian(method):
    """``I - S`` against central differences of ``G`` (error ~ eps^(2/3) relative to the entries)."""
    scene = SCENES["damped_chain"]()
    system = scene.system
    A = mslab.get_method(method).A
    dt = 0.02
    x, v = moved(scene, spread=0.05)
    X, V = stage_points(system, A, x, v, dt)
    U = V.ravel()
    J = np.eye(U.size) - coupled._dense_coupling(system, A, X, V, dt)
    step = 1e-6
    fd = np.empty_like(J)
    for c in range(U.size):
        e = np.zeros(U.size)
        e[c] = step
        fd[:, c] = (residual(system, A, x, v, dt, U + e) - residual(system, A, x, v, dt, U - e)) / (2 * step)
    scale = np.abs(J).max()
    assert np.abs(J - fd).max() <= 1e-7 * scale
    # a planted error (stage 1's coupling into stage 0 dropped) is far outside that bound
    wrong = J.copy()
    wrong[:x.size, x.size:] = 0.0
    assert np.abs(wrong - fd).max() > 100 * 1e-7 * scale

@pytest.mark.parametrize("method", ["gauss2", "radau_iia2"])
def test_dense_and_sparse_runs_agree(method, monkeypatch):
    """A whole run with the dense assembly against the same run forced onto the sparse one."""
    scene = SCENES["damped_chain"]()
    dense = mslab.simulate(scene, method, dt=5e-3, t_end=0.2, backend="numpy")
    monkeypatch.setattr(coupled, "_dense_coupling", lambda system, A, X, V, dt:
                        coupled._sparse_coupling(system, A, X, V, dt).toarray())
    sparse = mslab.simulate(scene, method, dt=5e-3, t_end=0.2, backend="numpy")
    assert np.array_equal(dense.x, sparse.x) and np.array_equal(dense.v, sparse.v)
    assert dense.stats.n_iter == sparse.stats.n_iter
