import numpy as np
import pytest

from mslab.claims import ClaimError, claim


def test_true_claim_prints_statement_and_numbers(capsys):
    claim("halving h quarters the error", np.float64(3.9) > 3.5, id="quarter", ratio=3.9123, n=4, tag="ok")
    out = capsys.readouterr().out
    assert out == "claim holds: [quarter] halving h quarters the error  (ratio = 3.91, n = 4, tag = ok)\n"


def test_false_claim_fails_the_cell_and_names_it():
    with pytest.raises(ClaimError, match="claim false: bounded  \\(drift = 0.5\\)"):
        claim("bounded", np.bool_(False), drift=0.5)
    with pytest.raises(AssertionError):          # nbval and pytest see an assertion
        claim("anything", 0)


from mslab.claims import fits, numbers_in, parse_printed  # noqa: E402


def test_numbers_as_written_with_their_digits():
    found = [(round(n.value, 12), n.half_ulp) for n in numbers_in("14.5 and 1e-6, 2 × 10⁻³, √6, 1/2, 178")]
    assert found == [(14.5, 0.05), (1e-6, 5e-7), (2e-3, 5e-4), (round(6 ** 0.5, 12), 0.0), (0.5, 0.0),
                     (178.0, 0.5)]
    assert [n.value for n in numbers_in(r"$\frac{1}{2}$ and $10^{-4}$")] == [0.5, 1e-4]


def test_printed_values_are_read_from_the_claim_line():
    (p,) = parse_printed("claim holds: [k2] rk4 is faster  (ratio = 14.53, k2 = 3.0, lumped = 0.70, 0.51)\n")
    assert p.id == "k2" and p.statement == "rk4 is faster"
    assert [v for v, _ in p.values] == [14.53, 3.0, 0.70, 0.51]


def test_a_number_fits_its_printed_value_to_its_own_digits_only():
    values = ((14.53, 0.005),)
    (n14,), (n146,), (n15,) = numbers_in("14.5"), numbers_in("14.6"), numbers_in("15")
    assert fits("equal", n14, None, values) and fits("equal", n15, None, values)
    assert not fits("equal", n146, None, values)
    assert fits("magnitude", None, (10.0, 99.0), values)
    assert not fits("magnitude", None, (100.0, 999.0), values)


def test_a_multiple_of_a_root_is_one_number():
    assert [round(n.value, 6) for n in numbers_in(r"RK4 reaches $2\sqrt 2$, i.e. 2√2")] == [2.828427, 2.8]


def test_shares_are_ratios_in_0_1_or_percents_printed_with_their_sign():
    (p,) = parse_printed("claim holds: [s] it loses energy  (ratio = 0.21, lost = 62 %, k = 178, n = 31)\n")
    assert [v for v, _ in p.shares] == [0.21, 0.62]
    assert p.shares[1][1] == 0.005                      # half a unit of "62 %", as a share


def test_share_words_have_two_sided_meanings_symmetric_in_the_complement():
    from mslab.claims import FRACTIONS, share_range
    assert share_range(0.5) == (0.5 / 1.1, 0.5 / 0.9)   # as "half" among the magnitude words
    lo, hi = share_range(0.9)
    assert (round(lo, 6), round(hi, 6)) == (round(1 - 0.1 / 0.9, 6), round(1 - 0.1 / 1.1, 6))
    for nominal, lo, hi in FRACTIONS.values():
        assert 0 <= lo <= nominal <= hi <= 1
