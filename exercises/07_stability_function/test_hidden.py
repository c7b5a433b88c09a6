"""Hidden tests of exercise 07 (graded, not released)."""

import numpy as np
import pytest

from mslab.grading.checks import check_array, check_scalar
from mslab.integrators import get_method

MODULE = "stability_function"


def stage_recursion(A, b, z):
    """R(z) by running the stages on y' = z y with y_0 = 1 (no matrix inverse)."""
    s = len(b)
    Y = []
    for i in range(s):
        Y.append(1.0 + z * sum(A[i, j] * Y[j] for j in range(i)))
    return 1.0 + z * sum(b[i] * Y[i] for i in range(s))


def left_end(A, b):
    """Where |R(x)| = 1 closest to 0 on the negative axis, from the polynomial's roots."""
    s = len(b)
    coef = [1.0] + [float(b @ np.linalg.matrix_power(A, k - 1) @ np.ones(s)) for k in range(1, s + 1)]
    poly = np.polynomial.Polynomial(coef)
    roots = []
    for target in (1.0, -1.0):
        for r in (poly - target).roots():
            if abs(r.imag) < 1e-9 and r.real < -1e-9:
                roots.append(r.real)
    for r in sorted(roots, reverse=True):
        if abs(poly(r - 1e-7)) > 1.0:
            return r
    raise AssertionError("no left end")


@pytest.mark.points(2)
def test_any_explicit_tableau_matches_the_stage_recursion(student):
    rng = np.random.default_rng(12)
    A = np.tril(rng.uniform(-1, 1, (5, 5)), k=-1)
    b = rng.uniform(0, 1, 5)
    z = rng.normal(size=7) + 1j * rng.normal(size=7)
    check_array(student.stability_function(A, b, z), stage_recursion(A, b, z), rtol=1e-10, atol=1e-12,
                what="R(z)")


@pytest.mark.points(2)
def test_rk3_and_rk4_intervals(student):
    for name in ("rk3", "rk4"):
        m = get_method(name)
        check_scalar(student.real_stability_interval(m.A, m.b), left_end(m.A, m.b), rtol=1e-9,
                     what=f"{name}: a")


@pytest.mark.points(1)
def test_interval_of_a_damped_euler_variant(student):
    # two half Euler steps: R = (1 + z/2)^2, so |R| <= 1 down to z = -4
    A = np.array([[0.0, 0.0], [0.5, 0.0]])
    b = np.array([0.5, 0.5])
    check_scalar(student.real_stability_interval(A, b), left_end(A, b), rtol=1e-9, what="a")


@pytest.mark.points(1)
def test_interval_of_a_tableau_drawn_at_grading(student):
    # s Euler substeps of random lengths c_i (A[i, :i] = c[:i], b = c): R(z) = prod(1 + c_i z),
    # |R| <= 1 on the whole of [a, 0] for near-equal substeps; a lies anywhere in about [-17, -2]
    rng = np.random.default_rng()
    s = int(rng.integers(2, 5))
    c = rng.uniform(0.7, 1.3, s)
    c *= rng.uniform(0.5, 2.0) / c.sum()
    A = np.zeros((s, s))
    for i in range(1, s):
        A[i, :i] = c[:i]
    b = c.copy()
    check_scalar(student.real_stability_interval(A, b), left_end(A, b), rtol=1e-9, what="a")
    z = rng.normal(size=5) + 1j * rng.normal(size=5)
    check_array(student.stability_function(A, b, z), stage_recursion(A, b, z), rtol=1e-10, atol=1e-12,
                what="R(z)")
