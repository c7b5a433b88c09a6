"""Hidden tests of exercise 08 (graded, not released)."""

import numpy as np
import pytest

from mslab.effects.colliders import Plane
from mslab.grading.checks import check_array

MODULE = "penalty_collision"


def tilted(dim, seed):
    rng = np.random.default_rng(seed)
    n = rng.normal(size=dim)
    return n / np.linalg.norm(n), rng


@pytest.mark.points(2)
def test_tilted_plane_in_3d_matches_the_library(student):
    n, rng = tilted(3, 15)
    x, v = rng.normal(size=(10, 3)) * 0.3, rng.normal(size=(10, 3))
    plane = Plane(n, 0.1, stiffness=5e3, friction=0.6, slip_velocity=1e-3)
    check_array(student.plane_contact_force(x, v, n, 0.1, 5e3, 0.6, 1e-3), plane.force(x, v),
                rtol=1e-9, atol=1e-9, what="force")


@pytest.mark.points(2)
def test_normal_force_is_minus_energy_gradient(student):
    n, rng = tilted(2, 16)
    x = rng.normal(size=(5, 2)) * 0.3

    def energy(y):
        p = np.maximum(0.2 - y @ n, 0.0)
        return 0.5 * 800.0 * np.sum(p * p)

    eps = 1e-7
    grad = np.zeros_like(x)
    for idx in np.ndindex(*x.shape):
        dx = np.zeros_like(x)
        dx[idx] = eps
        grad[idx] = (energy(x + dx) - energy(x - dx)) / (2 * eps)
    f = student.plane_contact_force(x, np.zeros_like(x), n, 0.2, 800.0, 0.0, 1e-3)
    check_array(f, -grad, rtol=1e-5, atol=1e-6, what="force")


@pytest.mark.points(2)
def test_friction_opposes_sliding_and_obeys_coulomb(student):
    n, rng = tilted(3, 17)
    x = -0.05 * np.ones((6, 1)) * n[None, :] + 0.0
    v = rng.normal(size=(6, 3))
    k, mu = 1e3, 0.5
    f = student.plane_contact_force(x, v, n, 0.0, k, mu, 1e-4)
    check_array(f @ n, np.full(6, k * 0.05), rtol=1e-9, what="normal component")
    ft = f - (f @ n)[:, None] * n
    vt = v - (v @ n)[:, None] * n
    assert np.all(np.sum(ft * vt, axis=1) < 0), "friction must oppose the tangential velocity"
    check_array(np.linalg.norm(ft, axis=1), np.full(6, mu * k * 0.05), rtol=1e-5, what="|f_t| when sliding")


@pytest.mark.points(1)
def test_a_plane_drawn_at_grading(student):
    # fresh plane, state and coefficients every grading: no table of answers can pass
    rng = np.random.default_rng()
    dim = int(rng.integers(2, 4))
    n = rng.normal(size=dim)
    n /= np.linalg.norm(n)
    x, v = rng.normal(size=(7, dim)) * 0.3, rng.normal(size=(7, dim))
    offset, k, mu, eps = float(rng.uniform(-0.1, 0.1)), float(rng.uniform(1e2, 1e4)), \
        float(rng.uniform(0, 1)), 1e-3
    plane = Plane(n, offset, stiffness=k, friction=mu, slip_velocity=eps)
    check_array(student.penetration_depth(x, n, offset), offset - x @ n, rtol=1e-12, atol=1e-12, what="depth")
    check_array(student.plane_contact_force(x, v, n, offset, k, mu, eps), plane.force(x, v),
                rtol=1e-9, atol=1e-9, what="force")
