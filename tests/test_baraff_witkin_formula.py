"""baraff_witkin's docstring formula, evaluated as written, is the code's step (issue 41)."""

import dataclasses

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import mslab
from mslab.scenes.generators import chain


def _jacobians(system, x, v):
    n = x.size
    K, D = sp.csr_matrix((n, n)), sp.csr_matrix((n, n))
    for e in system.effects:
        k, d = e.jacobians(x, v)
        K = K + (k if k is not None else 0)
        D = D + (d if d is not None else 0)
    return K, D


def test_docstring_formula_is_the_step():
    # a swinging chain with spring damping: rotating springs, velocity-dependent forces
    scene = chain(6, dim=2, stiffness=400.0, damping=0.5)
    v0 = np.random.default_rng(7).normal(size=scene.state0.v.shape) * ~scene.system.pinned[:, None]
    scene = dataclasses.replace(scene, state0=mslab.State(scene.state0.x, v0))
    h = 0.02
    sim = mslab.Simulation(scene, "baraff_witkin", dt=h, t_end=2 * h, backend="numpy")
    sim.advance(1)
    x1, v1 = sim.state.x, sim.state.v
    system = scene.system
    xn, vn = scene.state0.x, scene.state0.v
    free = np.repeat(~system.pinned, system.dim)
    mass = np.repeat(system.mass, system.dim)
    K, D = _jacobians(system, xn + h * vn, vn)
    f = system.force(xn + h * vn, vn).ravel()
    A = (sp.diags(mass) - h * h * K - h * D).tocsc()[free][:, free]
    dv = np.zeros(xn.size)
    dv[free] = spla.spsolve(A, h * f[free])
    v_next = vn.ravel() + dv
    np.testing.assert_allclose(v1.ravel(), v_next, rtol=0, atol=1e-12 * np.abs(v_next).max())
    np.testing.assert_allclose(x1.ravel(), xn.ravel() + h * v_next, rtol=0, atol=1e-12)
    # the old docstring's form (K, D and f at x_n) is another step on rotating springs
    K0, D0 = _jacobians(system, xn, vn)
    A0 = (sp.diags(mass) - h * h * K0 - h * D0).tocsc()[free][:, free]
    rhs = h * (system.force(xn, vn).ravel() + h * (K0 @ vn.ravel()))
    dv0 = np.zeros(xn.size)
    dv0[free] = spla.spsolve(A0, rhs[free])
    assert np.abs(vn.ravel() + dv0 - v_next).max() > 1e-6
