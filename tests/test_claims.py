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
