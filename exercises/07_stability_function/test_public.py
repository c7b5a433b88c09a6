"""Public tests of exercise 07 (run them from the folder above: ``pytest 07_stability_function``)."""

import math

import numpy as np
import pytest

from mslab.grading.checks import check_known, check_scalar
from mslab.grading.expected import Expected
from mslab.integrators import get_method
from mslab.stability import real_interval

MODULE = "stability_function"
EXPECTED = Expected(__file__)


def rk4_grid():
    """Points z of the complex plane where RK4's R(z) is checked."""
    re, im = np.meshgrid(np.linspace(-3, 1, 5), np.linspace(-3, 3, 4))
    return re + 1j * im


@pytest.mark.points(2)
def test_forward_euler_is_one_plus_z(student):
    # eq. 32 of the lecture notes: one Euler step multiplies y by (1 + h lam)
    euler = get_method("euler")
    z = np.array([-1.5 + 0.5j, 0.3j, -2.0, 0.25])
    check_known((student.stability_function(euler.A, euler.b, z),), (1.0 + z,),
                {"the leading 1 is missing: R(z) = 1 + z b^T (I - z A)^-1 1": (z,)}, whats=("R(z)",))


@pytest.mark.points(2)
def test_rk4_is_the_taylor_polynomial(student):
    rk4, z = get_method("rk4"), rk4_grid()
    expected = sum(z**k / math.factorial(k) for k in range(5))
    check_known((student.stability_function(rk4.A, rk4.b, z),), (expected,),
                {**EXPECTED.arrays("rk4_transposed")[1],  # a common slip, A transposed (expected.json)
                 "the leading 1 is missing: R(z) = 1 + z b^T (I - z A)^-1 1": (expected - 1.0,)},
                whats=("R(z)",), rtol=1e-12, atol=1e-12)


@pytest.mark.points(2)
def test_euler_and_heun_intervals_end_at_minus_two(student):
    for name in ("euler", "heun"):
        m = get_method(name)
        check_scalar(student.real_stability_interval(m.A, m.b), -2.0, rtol=1e-9, what=f"{name}: a", mistakes={
            "a is the left end of [a, 0]: a negative number": 2.0,
            "the end of the bracket (|R(-4)| > 1), not bisected down to where |R| = 1": -4.0})
    # not -2 for every method: RK4's interval reaches about -2.785 (the library's value)
    rk4 = get_method("rk4")
    check_scalar(student.real_stability_interval(rk4.A, rk4.b), float(real_interval("rk4")), rtol=1e-8,
                 what="rk4: a")
