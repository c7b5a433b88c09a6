"""Public tests of exercise 11 (run them from the folder above: ``pytest 11_shear_bend_springs``)."""

import numpy as np
import pytest

from mslab.grading.checks import as_numbers, check_array, check_known, check_shape
from mslab.grading.expected import Expected
from mslab.scenes import grid_springs

MODULE = "cloth_springs"
EXPECTED = Expected(__file__)  # the sheet's answers and the known mistakes', as numbers (expected.json)


def as_set(pairs, n_particles):
    """Unordered pairs as a set; fails on duplicates, self-springs and indices off the grid."""
    pairs = np.asarray(pairs)
    assert pairs.ndim == 2 and pairs.shape[1] == 2, f"pairs: shape {pairs.shape}, expected (n_springs, 2)"
    assert len(pairs) <= n_particles * (n_particles - 1) // 2, f"{len(pairs)} pairs: more than there are"
    found = set()
    for a, b in pairs.tolist():
        assert a != b and 0 <= a < n_particles and 0 <= b < n_particles, f"bad pair ({a}, {b})"
        key = (min(a, b), max(a, b))
        assert key not in found, f"pair {key} appears twice"
        found.add(key)
    return found


def lengths(x, pairs):
    pairs = np.asarray(pairs)
    return np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)


def shear_grid():
    """The sheet of the shear test: (n_rows, n_cols, spacing h, theta)."""
    return 4, 5, 0.2, np.radians(25.0)


@pytest.mark.points(2)
def test_structural_springs_of_a_3_by_4_grid(student):
    got = as_set(student.grid_springs(3, 4, "structural"), 12)
    assert len(got) == 17, f"{len(got)} structural springs, expected 17"
    assert got == as_set(grid_springs((3, 4), "structural"), 12), "not the neighbours along rows and columns"


@pytest.mark.points(2)
def test_shear_springs_are_both_diagonals_of_every_cell(student):
    got = as_set(student.grid_springs(4, 3, "shear"), 12)
    assert len(got) == 12, f"{len(got)} shear springs, expected 12 (two per cell)"
    assert got == as_set(grid_springs((4, 3), "shear"), 12), "not the two diagonals of each cell"


@pytest.mark.points(1)
def test_bend_springs_of_a_4_by_5_grid(student):
    got = as_set(student.grid_springs(4, 5, "bend"), 20)
    expected = as_set(grid_springs((4, 5), "bend"), 20)
    # the pairs that bend springs laid along the diagonals add, and the hint naming that mistake
    [(hint, (pairs,))] = EXPECTED.arrays("bend_4_by_5")[1].items()
    diagonal = {(int(a), int(b)) for a, b in pairs}
    assert got == expected, f"{len(got)} bend springs, expected {len(expected)}" + (
        f": likely mistake: {hint}" if got - expected and got - expected <= diagonal else "")


@pytest.mark.points(2)
def test_the_shear_mode_is_free_for_structural_springs_only(student):
    n_rows, n_cols, h, theta = shear_grid()
    x = as_numbers(student.sheared(n_rows, n_cols, h, theta), what="x")
    check_shape(x, (20, 2), what="x")
    y, wrong = EXPECTED.arrays("sheared_rows")  # the particles' heights y
    check_known((x[:, 1],), y, wrong, whats=("y",))
    structural, shear = grid_springs((n_rows, n_cols), "structural"), grid_springs((n_rows, n_cols), "shear")
    (flat_structural, flat_shear), _ = EXPECTED.arrays("flat_lengths")  # the springs' lengths before shearing
    check_array(lengths(x, structural), flat_structural, rtol=1e-12, atol=1e-14,
                what="structural spring lengths after shearing")
    change = np.abs(lengths(x, shear) - flat_shear)
    assert change.min() > 0.01 * h, "every shear spring must change its length under shear"
