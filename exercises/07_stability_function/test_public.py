"""Public tests of exercise 07 (run them from the folder above: ``pytest 07_stability_function``)."""

import math

import numpy as np
import pytest

from mslab.grading.checks import check_array, check_scalar
from mslab.integrators import get_method
from mslab.stability import real_interval

MODULE = "stability_function"


@pytest.mark.points(2)
def test_forward_euler_is_one_plus_z(student):
    # eq. 32 of the lecture notes: one Euler step multiplies y by (1 + h lam)
    euler = get_method("euler")
    z = np.array([-1.5 + 0.5j, 0.3j, -2.0, 0.25])
    check_array(student.stability_function(euler.A, euler.b, z), 1.0 + z, what="R(z)")


@pytest.mark.points(2)
def test_rk4_is_the_taylor_polynomial(student):
    rk4 = get_method("rk4")
    re, im = np.meshgrid(np.linspace(-3, 1, 5), np.linspace(-3, 3, 4))
    z = re + 1j * im
    expected = sum(z**k / math.factorial(k) for k in range(5))
    check_array(student.stability_function(rk4.A, rk4.b, z), expected, rtol=1e-12, atol=1e-12, what="R(z)")


@pytest.mark.points(2)
def test_euler_and_heun_intervals_end_at_minus_two(student):
    for name in ("euler", "heun"):
        m = get_method(name)
        check_scalar(student.real_stability_interval(m.A, m.b), -2.0, rtol=1e-9, what=f"{name}: a")
    # not -2 for every method: RK4's interval reaches about -2.785 (the library's value)
    rk4 = get_method("rk4")
    check_scalar(student.real_stability_interval(rk4.A, rk4.b), float(real_interval("rk4")), rtol=1e-8,
                 what="rk4: a")
