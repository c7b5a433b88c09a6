"""Public tests of exercise 01 (run them from the folder above: ``pytest 01_spring_force``)."""

import numpy as np
import pytest

from mslab.effects.springs import Springs
from mslab.grading.checks import check_array, check_known, check_shape
from mslab.grading.expected import Expected

MODULE = "spring_force"
EXPECTED = Expected(__file__)  # the known mistakes' answers, as numbers (expected.json)


def mslab_springs(springs, stiffness, rest_length, n):
    return Springs(springs, stiffness, rest_length, np.zeros(len(springs)), n)


def single_spring():
    # two particles 1.5 apart, rest length 1, k = 10
    return np.array([[0.0, 0.0], [1.5, 0.0]]), np.array([[0, 1]]), np.array([10.0]), np.array([1.0])


def small_net():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(5, 2))
    springs = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [0, 2], [1, 4]])
    return x, springs, rng.uniform(1, 50, 6), rng.uniform(0.5, 1.5, 6)


def three_particles():
    rng = np.random.default_rng(3)
    return rng.normal(size=(3, 2)), np.array([[0, 1], [1, 2]]), np.array([20.0, 5.0]), np.array([0.7, 1.3])


@pytest.mark.points(2)
def test_single_stretched_spring(student):
    # pulled together with |f| = 5
    f = student.spring_forces(*single_spring())
    check_known((f,), (np.array([[5.0, 0.0], [-5.0, 0.0]]),), EXPECTED.arrays("single_spring")[1],
                whats=("forces",))


@pytest.mark.points(2)
def test_forces_of_a_small_net(student):
    x, springs, k, rest = small_net()
    expected = mslab_springs(springs, k, rest, 5).force(x, np.zeros_like(x))
    check_known((student.spring_forces(x, springs, k, rest),), (expected,),
                EXPECTED.arrays("small_net")[1], whats=("forces",), rtol=1e-10, atol=1e-10)


@pytest.mark.points(1)
def test_internal_forces_sum_to_zero(student):
    rng = np.random.default_rng(2)
    x = rng.normal(size=(4, 3))
    springs = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    k, rest = np.full(4, 7.0), np.full(4, 0.8)
    f = student.spring_forces(x, springs, k, rest)
    check_shape(f, (4, 3), what="forces")
    check_array(f.sum(axis=0), np.zeros(3), atol=1e-10, what="sum of forces")
    # and not by being zero: the forces are the library's
    check_array(f, mslab_springs(springs, k, rest, 4).force(x, 0 * x), rtol=1e-10, atol=1e-10, what="forces")


@pytest.mark.points(3)
def test_jacobian_by_finite_differences(student):
    x, springs, k, rest = three_particles()
    ref = mslab_springs(springs, k, rest, 3)
    eps = 1e-6
    K = np.zeros((6, 6))
    for c in range(6):
        dx = np.zeros(6)
        dx[c] = eps
        fp = ref.force(x + dx.reshape(3, 2), 0 * x).ravel()
        fm = ref.force(x - dx.reshape(3, 2), 0 * x).ravel()
        K[:, c] = (fp - fm) / (2 * eps)
    check_known((student.spring_jacobian(x, springs, k, rest),), (K,),
                EXPECTED.arrays("three_particles")[1], whats=("Jacobian",), rtol=1e-6, atol=1e-6)
