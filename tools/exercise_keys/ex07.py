"""Key of exercise 07 (stability functions): R(z) of a tableau read with A transposed."""

import numpy as np


def _rk4_transposed(t):
    rk4, z = t.get_method("rk4"), t.rk4_grid()
    # stage i using column i of A: R(z) = 1 + z b^T (I - z A^T)^-1 1, a finite series (A^T is nilpotent)
    At, ones = rk4.A.T, np.ones(4)
    transposed = 1.0 + z * sum(float(rk4.b @ np.linalg.matrix_power(At, k) @ ones) * z**k for k in range(4))
    hint = "A transposed: stage i uses row i of A, R(z) = 1 + z b^T (I - z A)^-1 1"
    return {"mistakes": {hint: [transposed]}}


CASES = {"rk4_transposed": _rk4_transposed}
