"""Hidden tests of exercise 01 (graded, not released)."""

import numpy as np
import pytest

from mslab.effects.springs import Springs
from mslab.grading.checks import check_array, check_shape

MODULE = "spring_force"


def net(seed, n, dim, n_springs):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, dim))
    springs = np.array([rng.choice(n, 2, replace=False) for _ in range(n_springs)])
    return x, springs, rng.uniform(1, 100, n_springs), rng.uniform(0.2, 2.0, n_springs)


@pytest.mark.points(2)
def test_forces_in_3d_with_shared_particles(student):
    x, springs, k, rest = net(10, 8, 3, 20)
    expected = Springs(springs, k, rest, np.zeros(20), 8).force(x, 0 * x)
    check_array(student.spring_forces(x, springs, k, rest), expected, rtol=1e-9, atol=1e-9, what="forces")


@pytest.mark.points(2)
def test_jacobian_matches_the_library(student):
    x, springs, k, rest = net(11, 6, 3, 9)
    K, _ = Springs(springs, k, rest, np.zeros(9), 6).jacobians(x, 0 * x)
    check_array(student.spring_jacobian(x, springs, k, rest), K.toarray(), rtol=1e-9, atol=1e-9,
                what="Jacobian")


@pytest.mark.points(1)
def test_jacobian_is_symmetric(student):
    x, springs, k, rest = net(12, 5, 2, 7)
    K = student.spring_jacobian(x, springs, k, rest)
    check_shape(K, (10, 10), what="Jacobian")
    check_array(K, K.T, rtol=1e-12, atol=1e-12, what="Jacobian (compared with its transpose)")
    # a symmetric matrix is not enough: K d must be the derivative of the force along d
    d = np.random.default_rng(14).normal(size=x.shape)
    eps = 1e-6
    ref = Springs(springs, k, rest, np.zeros(7), 5)
    slope = (ref.force(x + eps * d, 0 * x) - ref.force(x - eps * d, 0 * x)) / (2 * eps)
    check_array(K @ d.ravel(), slope.ravel(), rtol=1e-6, atol=1e-6, what="Jacobian times a direction")


@pytest.mark.points(2)
def test_force_is_minus_energy_gradient(student):
    x, springs, k, rest = net(13, 4, 2, 5)

    def energy(y):
        length = np.linalg.norm(y[springs[:, 0]] - y[springs[:, 1]], axis=1)
        return 0.5 * np.sum(k * (length - rest) ** 2)

    eps = 1e-6
    grad = np.zeros_like(x)
    for idx in np.ndindex(*x.shape):
        dx = np.zeros_like(x)
        dx[idx] = eps
        grad[idx] = (energy(x + dx) - energy(x - dx)) / (2 * eps)
    check_array(student.spring_forces(x, springs, k, rest), -grad, rtol=1e-6, atol=1e-6, what="forces")


@pytest.mark.points(1)
def test_random_net_drawn_at_grading(student):
    # fresh inputs every grading: no table of answers can pass
    rng = np.random.default_rng()
    n, dim, m = int(rng.integers(4, 9)), int(rng.integers(1, 4)), int(rng.integers(3, 12))
    x = rng.normal(size=(n, dim))
    springs = np.array([rng.choice(n, 2, replace=False) for _ in range(m)])
    k, rest = rng.uniform(1, 100, m), rng.uniform(0.2, 2.0, m)
    ref = Springs(springs, k, rest, np.zeros(m), n)
    check_array(student.spring_forces(x, springs, k, rest), ref.force(x, 0 * x), rtol=1e-9, atol=1e-9,
                what="forces")
    check_array(student.spring_jacobian(x, springs, k, rest), ref.jacobians(x, 0 * x)[0].toarray(),
                rtol=1e-9, atol=1e-9, what="Jacobian")
