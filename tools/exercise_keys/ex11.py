"""Key of exercise 11 (cloth springs): the rows of the sheared sheet, the flat lengths, bend on diagonals."""

import numpy as np

from mslab.scenes import grid_springs


def _bend_on_diagonals(t):
    # a 4 x 5 grid: pairs two rows and two columns apart
    pairs = sorted({tuple(sorted((i * 5 + j, (i + 2) * 5 + j + s))) for i in range(2) for j in range(5)
                    for s in (-2, 2) if 0 <= j + s < 5})
    return {"mistakes": {"bend springs skip one particle along rows and columns, not along diagonals":
                         [np.array(pairs, dtype=float)]}}


def _rows(t):
    n_rows, n_cols, h, theta = t.shear_grid()
    i, _ = np.divmod(np.arange(n_rows * n_cols), n_cols)
    return {"expected": [i * h * np.cos(theta)], "mistakes": {
        "cos and sin swapped: the rows rise by h cos(theta) and move sideways by h sin(theta)":
        [i * h * np.sin(theta)]}}


def _flat_lengths(t):
    n_rows, n_cols, h, _ = t.shear_grid()
    i, j = np.divmod(np.arange(n_rows * n_cols), n_cols)
    flat = np.stack([j * h, i * h], axis=1)
    return {"expected": [t.lengths(flat, grid_springs((n_rows, n_cols), kind))
                         for kind in ("structural", "shear")]}


CASES = {"bend_4_by_5": _bend_on_diagonals, "sheared_rows": _rows, "flat_lengths": _flat_lengths}
