"""Public tests of exercise 08 (run them from the folder above: ``pytest 08_penalty_collision``)."""

import numpy as np
import pytest

from mslab.effects.colliders import Plane
from mslab.grading.checks import check_known, check_shape
from mslab.grading.expected import Expected

MODULE = "penalty_collision"
EXPECTED = Expected(__file__)  # the known mistakes' answers, as numbers (expected.json)

NORMAL = np.array([0.0, 1.0])


def resting_contact():
    """Two particles at rest, one 0.1 below the floor y = 0: (x, v, normal, offset, k, mu, eps)."""
    x = np.array([[0.0, -0.1], [2.0, 0.3]])
    return x, np.zeros_like(x), NORMAL, 0.0, 1000.0, 0.0, 1e-3


def sliding_contact():
    """Eight particles moving about the plane y = 0.05, with friction: (x, v, normal, offset, k, mu, eps)."""
    rng = np.random.default_rng(14)
    x, v = rng.normal(size=(8, 2)) * 0.2, rng.normal(size=(8, 2))
    return x, v, NORMAL, 0.05, 2e3, 0.4, 1e-2


@pytest.mark.points(1)
def test_depth_is_signed_distance_below_the_plane(student):
    x = np.array([[0.0, -0.1], [2.0, 0.3], [1.0, 0.0]])
    depth = np.array([0.1, -0.3, 0.0])
    check_known((student.penetration_depth(x, NORMAL, 0.0),), (depth,), whats=("depth",),
                mistakes={"the sign: the depth offset - n.x is positive inside the wall": (-depth,)})


@pytest.mark.points(2)
def test_frictionless_push_is_a_spring(student):
    f = student.plane_contact_force(*resting_contact())
    check_known((f,), (np.array([[0.0, 100.0], [0.0, 0.0]]),), EXPECTED.arrays("resting_contact")[1],
                whats=("force",))


@pytest.mark.points(3)
def test_with_friction_matches_the_library(student):
    x, v, normal, offset, stiffness, friction, slip = sliding_contact()
    plane = Plane(normal, offset, stiffness=stiffness, friction=friction, slip_velocity=slip)
    f = student.plane_contact_force(x, v, normal, offset, stiffness, friction, slip)
    check_shape(f, (8, 2), what="force")
    check_known((f,), (plane.force(x, v),), EXPECTED.arrays("sliding_contact")[1],
                whats=("force",), rtol=1e-10, atol=1e-10)
