"""Key of exercise 12 (your own third-order method): order conditions with wrong nodes, wrong stages."""

import numpy as np
from ex04 import rk_stages


def _column_nodes(t):
    A, b = t.KUTTA3
    c = A.sum(axis=0)  # a common slip: the column sums
    return {"mistakes": {"the nodes c = A 1 are the row sums of A, not its column sums":
                         [np.array([b.sum() - 1, b @ c - 1 / 2, b @ c**2 - 1 / 3, b @ A @ c - 1 / 6])]}}


def _kutta_step(t):
    prob, v0 = t.moving_chain()
    A, b = t.KUTTA3
    return {"mistakes": rk_stages(prob, prob.x0, v0, t.DT, A, b)}


CASES = {"kutta_column_nodes": _column_nodes, "kutta_step": _kutta_step}
