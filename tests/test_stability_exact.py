"""The real stability interval of a tableau, exact (issue 41): narrow gaps, no cap, built-ins unchanged."""

import math
from fractions import Fraction

import numpy as np
import pytest

from mslab import stability as st
from mslab.integrators import ExplicitRK, ImplicitRK
from mslab.integrators.base import get_method, methods
from mslab.stability.functions import tableau
from mslab.stability.limits import scanned_real_interval


def _nested(c: list[Fraction]) -> ExplicitRK:
    """The explicit tableau with ``R(z) = 1 + z + c[0] z^2 + c[1] z^3 + ...`` (a subdiagonal chain)."""
    s = len(c) + 1
    ratios = [c[0]] + [c[k] / c[k - 1] for k in range(1, len(c))]  # A[i][i-1], from the last stage down
    A = [[Fraction(0)] * s for _ in range(s)]
    for i in range(1, s):
        A[i][i - 1] = ratios[s - 1 - i]
    return ExplicitRK(A, [Fraction(0)] * (s - 1) + [Fraction(1)], name="narrow", order=1)


def test_narrow_gap_below_minus_one():
    # R = 1 + z + c z^2 dips below -1 only on a 0.023 wide gap around -4 (c just under 1/8):
    # the scan of the old code stepped over it and reported the far end -8.00006
    c = Fraction(1, 8) - Fraction(1, 10**6)
    m = _nested([c])
    z = np.array([-3.9, -4.0, -8.0], dtype=complex)
    np.testing.assert_allclose(st.amplification(m, z), 1 + z + float(c) * z**2, rtol=1e-14)
    cf = float(c)
    first = (-1 + math.sqrt(1 - 8 * cf)) / (2 * cf)   # the root of R = -1 nearest 0
    assert first == pytest.approx(-3.98872, abs=1e-5)
    assert st.real_interval(m) == pytest.approx(first, rel=1e-12)


def test_narrow_gap_above_plus_one():
    # T_3(1 + z/9) touches +1 at z = -13.5; + eps z^2 lifts it over 1 on a 0.03 wide gap
    eps = Fraction(1, 10**7)
    c2, c3 = Fraction(4, 27) + eps, Fraction(4, 729)
    m = _nested([c2, c3])
    z = np.array([-13.5, -4.5, -17.0], dtype=complex)
    np.testing.assert_allclose(st.amplification(m, z), 1 + z + float(c2) * z**2 + float(c3) * z**3,
                               rtol=1e-13)
    a, b = float(c3), float(c2)
    first = (-b + math.sqrt(b * b - 4 * a)) / (2 * a)  # R = 1 at z (1 + c2 z + c3 z^2) = 0, nearest 0
    assert -13.6 < first < -13.4
    xs = np.linspace(-13.6, -13.4, 200_001)   # and by brute force: the first |R| > 1 from the right
    over = xs[np.abs(1 + xs + b * xs**2 + a * xs**3) > 1.0]
    assert over[-1] == pytest.approx(first, abs=2e-6)
    assert st.real_interval(m) == pytest.approx(first, rel=1e-12)


def test_theta_method_beyond_a_million():
    # theta-method: R = (1 + (1 - theta) z) / (1 - theta z) -> -(1 - theta) / theta < -1 at -inf;
    # R = -1 at z = -2 / (1 - 2 theta) = -1e7 (the old scan stopped at 1e6 and said -inf)
    theta = 0.5 - 1e-7
    m = ImplicitRK([[0.0, 0.0], [1 - theta, theta]], [1 - theta, theta], name="theta", order=1)
    assert st.real_interval(m) == pytest.approx(-2.0 / (1.0 - 2.0 * theta), rel=1e-9)
    assert st.real_interval(m) == pytest.approx(-1e7, rel=1e-6)


@pytest.mark.parametrize("name", [n for n in methods() if tableau(get_method(n)) is not None])
def test_builtin_intervals_unchanged(name):
    # the exact left end is the scan's (which stops at |R| <= 1 + 1e-10) to its tolerance,
    # and every printed table (4 decimals) stays the same
    m = get_method(name)
    exact, scanned = st.real_interval(m), scanned_real_interval(m)
    if math.isinf(scanned):
        assert exact == scanned
    else:
        assert exact == pytest.approx(scanned, rel=1e-9)
        assert f"{exact:.4f}" == f"{scanned:.4f}"
        assert abs(st.amplification(m, exact)) == pytest.approx(1.0, abs=1e-12)
