"""Exercise 11: structural, shear and bend springs and what they resist (lesson 09; lecture notes, §2.3)."""

import numpy as np


def grid_springs(n_rows, n_cols, kind):
    """Index pairs of one spring kind on an ``n_rows x n_cols`` grid (index ``i * n_cols + j``).

    Parameters
    ----------
    n_rows, n_cols : int
    kind : str
        ``"structural"``, ``"shear"`` or ``"bend"``.

    Returns
    -------
    pairs : ndarray of int, shape (n_springs, 2)
    """
    # BEGIN SOLUTION
    offsets = {"structural": [(0, 1), (1, 0)], "shear": [(1, 1), (1, -1)], "bend": [(0, 2), (2, 0)]}[kind]
    pairs = []
    for i in range(n_rows):
        for j in range(n_cols):
            for di, dj in offsets:
                k, m = i + di, j + dj
                if 0 <= k < n_rows and 0 <= m < n_cols:
                    pairs.append((i * n_cols + j, k * n_cols + m))
    return np.array(pairs, dtype=int).reshape(-1, 2)
    # END SOLUTION


def sheared(n_rows, n_cols, spacing, theta):
    """The sheet with its column lines tilted by ``theta``: ``(j h + i h sin(theta), i h cos(theta))``.

    Returns
    -------
    x : ndarray, shape (n_rows * n_cols, 2)
    """
    # BEGIN SOLUTION
    i, j = np.divmod(np.arange(n_rows * n_cols), n_cols)
    return np.stack([j * spacing + i * spacing * np.sin(theta), i * spacing * np.cos(theta)], axis=1)
    # END SOLUTION


def folded(n_rows, n_cols, spacing, phi, row):
    """The flat sheet ``(j h, i h, 0)`` with the rows above ``row`` rotated by ``phi`` about it.

    Returns
    -------
    x : ndarray, shape (n_rows * n_cols, 3)
    """
    # BEGIN SOLUTION
    i, j = np.divmod(np.arange(n_rows * n_cols), n_cols)
    d = np.maximum(i - row, 0) * spacing
    y = np.minimum(i, row) * spacing + d * np.cos(phi)
    return np.stack([j * spacing, y, d * np.sin(phi)], axis=1)
    # END SOLUTION
