"""Hidden tests of exercise 11 (graded, not released)."""

import numpy as np
import pytest

from mslab.grading.checks import as_numbers, check_array, check_shape
from mslab.scenes import grid_springs

MODULE = "cloth_springs"


def as_set(pairs, n_particles):
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


@pytest.mark.points(1)
def test_bend_springs_skip_one_particle(student):
    got = as_set(student.grid_springs(5, 6, "bend"), 30)
    assert len(got) == 5 * 4 + 6 * 3, f"{len(got)} bend springs, expected 38"
    assert got == as_set(grid_springs((5, 6), "bend"), 30)


@pytest.mark.points(1)
def test_the_fold_is_felt_by_bend_springs_only(student):
    n_rows, n_cols, h, phi, row = 6, 4, 0.1, np.radians(50.0), 2
    x = as_numbers(student.folded(n_rows, n_cols, h, phi, row), what="x")
    check_shape(x, (24, 3), what="x")
    i, j = np.divmod(np.arange(24), n_cols)
    flat = np.stack([j * h, i * h, np.zeros(24)], axis=1)
    d = np.maximum(i - row, 0) * h
    check_array(x[:, 2], d * np.sin(phi), atol=1e-14, what="z")
    for kind in ("structural", "shear"):
        pairs = grid_springs((n_rows, n_cols), kind)
        check_array(lengths(x, pairs), lengths(flat, pairs), rtol=1e-12, atol=1e-14, what=f"{kind} lengths")
    bend = grid_springs((n_rows, n_cols), "bend")
    across = (i[bend[:, 0]] - row) * (i[bend[:, 1]] - row) < 0          # one end below the hinge, one above
    shortened = lengths(flat, bend) - lengths(x, bend)
    assert across.any() and shortened[across].min() > 1e-3 * h, "bend springs across the hinge must shorten"


@pytest.mark.points(2)
def test_grids_drawn_at_grading(student):
    rng = np.random.default_rng()
    for _ in range(3):
        n_rows, n_cols = int(rng.integers(2, 10)), int(rng.integers(2, 10))
        n = n_rows * n_cols
        for kind in ("structural", "shear", "bend"):
            got = as_set(student.grid_springs(n_rows, n_cols, kind), n)
            assert got == as_set(grid_springs((n_rows, n_cols), kind), n), f"{kind} on {n_rows} x {n_cols}"
    theta, h = float(rng.uniform(0.1, 1.0)), float(rng.uniform(0.05, 0.5))
    x = as_numbers(student.sheared(n_rows, n_cols, h, theta), what="x")
    i, j = np.divmod(np.arange(n), n_cols)
    check_array(x, np.stack([j * h + i * h * np.sin(theta), i * h * np.cos(theta)], axis=1), what="sheared x")
