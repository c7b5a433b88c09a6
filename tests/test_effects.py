"""Effects: force = -grad(energy), Jacobians = finite differences, momentum, power."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mslab.effects import Damping, Gravity, Plane, Sphere, Springs


def num_grad(fun, x, eps=1e-6):
    g = np.zeros_like(x)
    for idx in np.ndindex(x.shape):
        xp, xm = x.copy(), x.copy()
        xp[idx] += eps
        xm[idx] -= eps
        g[idx] = (fun(xp) - fun(xm)) / (2 * eps)
    return g


def num_jac(fun, x, eps=1e-6):
    """d fun(x) / dx for fun: (n, dim) -> (n, dim), as an (n*dim, n*dim) matrix."""
    cols = []
    for idx in np.ndindex(x.shape):
        xp, xm = x.copy(), x.copy()
        xp[idx] += eps
        xm[idx] -= eps
        cols.append(((fun(xp) - fun(xm)) / (2 * eps)).ravel())
    return np.array(cols).T


def dense(m, size):
    return np.zeros((size, size)) if m is None else m.toarray()


def check_effect(effect, x, v, conservative=True, rtol=1e-5, atol=1e-6):
    size = x.size
    if conservative:
        grad = num_grad(effect.energy, x)
        f0 = effect.force(x, np.zeros_like(v))
        np.testing.assert_allclose(f0, -grad, rtol=rtol, atol=atol)
    jx, jv = effect.jacobians(x, v)
    fd_x = num_jac(lambda y: effect.force(y, v), x)
    fd_v = num_jac(lambda w: effect.force(x, w), v)
    np.testing.assert_allclose(dense(jx, size), fd_x, rtol=rtol, atol=atol)
    np.testing.assert_allclose(dense(jv, size), fd_v, rtol=rtol, atol=atol)
    f, p = effect.force_and_power(x, v)
    np.testing.assert_allclose(f, effect.force(x, v))
    # the power an effect reports is what its non-conservative part removes: -f_diss . v >= 0
    f_cons = effect.force(x, np.zeros_like(v)) if conservative else 0.0
    assert p == pytest.approx(-np.sum((f - f_cons) * v), rel=1e-9, abs=1e-12)
    assert p >= 0.0


@pytest.fixture
def rng():
    return np.random.default_rng(7)


def test_spring_matches_hooke_law_eq2():
    x = np.array([[0.0, 0.0], [3.0, 4.0]])
    s = Springs([[0, 1]], [10.0], [4.0], [0.0], 2)
    f = s.force(x, np.zeros_like(x))
    # f_0 = k (L - l) (x_0 - x_1)/l with l = 5, L = 4
    np.testing.assert_allclose(f[0], 10.0 * (4.0 - 5.0) * np.array([-3.0, -4.0]) / 5.0)
    np.testing.assert_allclose(f[1], -f[0])
    assert s.energy(x) == pytest.approx(0.5 * 10.0 * 1.0)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_springs_with_damping(rng, dim):
    n = 6
    x = rng.normal(size=(n, dim))
    v = rng.normal(size=(n, dim))
    pairs = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [0, 5], [1, 4]])
    s = Springs(pairs, rng.uniform(1, 10, 7), rng.uniform(0.2, 2, 7), rng.uniform(0, 2, 7), n)
    check_effect(s, x, v)
    np.testing.assert_allclose(s.force(x, v).sum(axis=0), 0.0, atol=1e-12)


def test_zero_length_spring_is_finite():
    x = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]])
    v = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    for rest in (0.0, 0.5):
        s = Springs([[0, 1]], [100.0], [rest], [1.0], 2)
        f, p = s.force_and_power(x, v)
        assert np.all(np.isfinite(f)) and np.isfinite(p) and np.isfinite(s.energy(x))
        jx, jv = s.jacobians(x, v)
        assert np.all(np.isfinite(jx.toarray())) and np.all(np.isfinite(jv.toarray()))


def test_zero_rest_length_spring_is_linear(rng):
    x = rng.normal(size=(2, 3))
    s = Springs([[0, 1]], [3.0], [0.0], [0.0], 2)
    np.testing.assert_allclose(s.force(x, x * 0)[0], -3.0 * (x[0] - x[1]))


def test_gravity_and_damping(rng):
    x = rng.normal(size=(4, 3))
    v = rng.normal(size=(4, 3))
    mass = rng.uniform(0.5, 2, 4)
    check_effect(Gravity([0, 0, -9.81], mass), x, v)
    check_effect(Damping(0.7, 4, 3), x, v, conservative=False)
    np.testing.assert_allclose(Damping(0.7, 4, 3).force(x, v), -0.7 * v)


@pytest.mark.parametrize("friction", [0.0, 0.4])
def test_plane_collider(rng, friction):
    x = rng.normal(size=(8, 3))
    v = rng.normal(size=(8, 3))
    plane = Plane([0.2, 1.0, 0.1], 0.0, 500.0, friction=friction, slip_velocity=0.3)
    assert np.any(x @ plane.normal < 0) and np.any(x @ plane.normal > 0)
    check_effect(plane, x, v)
    f = plane.force(x, v)
    outside = x @ plane.normal > 0
    np.testing.assert_array_equal(f[outside], 0.0)


@pytest.mark.parametrize("dim,friction", [(2, 0.0), (3, 0.0), (2, 0.5), (3, 0.5)])
def test_sphere_collider(rng, dim, friction):
    x = rng.normal(size=(10, dim)) * 0.8
    v = rng.normal(size=(10, dim))
    sphere = Sphere(np.zeros(dim) + 0.1, 1.0, 300.0, friction=friction, slip_velocity=0.2)
    check_effect(sphere, x, v)
    r = np.linalg.norm(x - 0.1, axis=1)
    np.testing.assert_array_equal(sphere.force(x, v)[r > 1.0], 0.0)


def test_friction_approaches_coulomb():
    x = np.array([[0.0, -0.01, 0.0]])
    v = np.array([[3.0, 0.0, 4.0]])
    plane = Plane([0, 1, 0], 0.0, 1000.0, friction=0.5, slip_velocity=1e-6)
    f = plane.force(x, v)[0]
    normal_force = 1000.0 * 0.01
    np.testing.assert_allclose(f[1], normal_force)
    np.testing.assert_allclose(f[[0, 2]], -0.5 * normal_force * np.array([3.0, 4.0]) / 5.0, rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_random_spring_networks(data):
    n = data.draw(st.integers(2, 7))
    dim = data.draw(st.integers(1, 3))
    seed = data.draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    x = rng.uniform(-2, 2, size=(n, dim))
    v = rng.normal(size=(n, dim))
    m = data.draw(st.integers(1, 12))
    i = rng.integers(0, n, m)
    j = (i + rng.integers(1, n, m)) % n
    pairs = np.stack([i, j], axis=1)
    lengths = np.linalg.norm(x[i] - x[j], axis=1)
    if lengths.min() < 0.05:
        return  # finite differences need a spring of non-vanishing length
    damped = data.draw(st.booleans())
    s = Springs(pairs, rng.uniform(0.1, 50, m), rng.uniform(0, 3, m),
                rng.uniform(0, 3, m) if damped else np.zeros(m), n)
    assert s.velocity_dependent == damped
    np.testing.assert_allclose(s.force(x, v).sum(axis=0), 0.0, atol=1e-9)
    check_effect(s, x, v, rtol=1e-4, atol=1e-5)
