"""The local step of the fast mass-spring method and the glue of one iteration, compiled.

Each spring ``q = (i, j)`` with stiffness ``k`` and rest length ``L`` is projected onto its
rest length: ``d_q = L (x_i - x_j) / |x_i - x_j|`` (the closest vector of length ``L`` to
the current one; ``d_q = 0`` for a spring of zero length, whose force is zero too). The
projections are scattered as ``J d = sum_q k_q d_q (e_i - e_j)``, the right-hand side term
of the global step (Liu et al. 2013, eq. 12). Since ``J d = f_spring(x) + L x`` with ``L``
the stiffness-weighted graph Laplacian, the local step is the spring force in disguise.

:func:`local_rhs` does the local step and writes the global step's right-hand side
``b + h^2 (J d + f_other)`` on the free particles in one compiled pass; :func:`update`
stores the global step's solution (plain, or Chebyshev-extrapolated) and returns the change.
Both are plain functions compiled on first use by :func:`mslab.jit.compiled`
(``numba.njit(cache=True)`` without fastmath: the numpy code's round-off);
:func:`projections_py` and :func:`local_rhs_numpy` are the uncompiled references the tests
hold them to.
"""

from __future__ import annotations

import numpy as np

from mslab.jit import compiled


def projections_py(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                   rest_length: np.ndarray, out: np.ndarray) -> None:
    """Add ``sum_q k_q d_q (e_i - e_j)`` to ``out`` (n_particles, dim) in place (plain loop)."""
    dim = x.shape[1]
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        length2 = 0.0
        for c in range(dim):
            diff = x[a, c] - x[b, c]
            length2 += diff * diff
        length = np.sqrt(length2)
        if length > 0.0:
            scale = stiffness[q] * rest_length[q] / length
            for c in range(dim):
                p = scale * (x[a, c] - x[b, c])
                out[a, c] += p
                out[b, c] -= p


def projection3(x: np.ndarray, a: int, b: int, stiffness: float, rest_length: float
                ) -> tuple[bool, float, float, float]:
    """Return ``(length > 0, k d)`` of the spring ``(a, b)`` in 3D: ``k L (x_a - x_b) / |x_a - x_b|``."""
    d0 = x[a, 0] - x[b, 0]
    d1 = x[a, 1] - x[b, 1]
    d2 = x[a, 2] - x[b, 2]
    length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if length > 0.0:
        scale = stiffness * rest_length / length
        return True, scale * d0, scale * d1, scale * d2
    return False, 0.0, 0.0, 0.0


def local_rhs_py(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                 rest_length: np.ndarray, extra: np.ndarray, base: np.ndarray, h2: float,
                 free_idx: np.ndarray, jd: np.ndarray, rhs: np.ndarray) -> None:
    """Local step and right-hand side: ``jd = J d + extra``, ``rhs = base + h2 jd[free_idx]``.

    ``extra`` (n_particles, dim) holds the other forces at the iterate; ``base`` and ``rhs``
    are (n_free, dim), ``rhs`` may be Fortran-ordered (the solvers read columns).
    """
    n, dim = x.shape
    for a in range(n):
        for c in range(dim):
            jd[a, c] = 0.0
    if dim == 3:  # unrolled: the common case, about twice as fast (the loop below is the same)
        for q in range(i.shape[0]):
            a = i[q]
            b = j[q]
            moved, p0, p1, p2 = projection3(x, a, b, stiffness[q], rest_length[q])
            if moved:
                jd[a, 0] += p0
                jd[a, 1] += p1
                jd[a, 2] += p2
                jd[b, 0] -= p0
                jd[b, 1] -= p1
                jd[b, 2] -= p2
    else:  # compiled with it by mslab.jit.compiled (a helper of this module)
        projections_py(x, i, j, stiffness, rest_length, jd)
    for a in range(n):
        for c in range(dim):
            jd[a, c] += extra[a, c]
    for c in range(dim):
        for r in range(free_idx.shape[0]):
            rhs[r, c] = base[r, c] + h2 * jd[free_idx[r], c]


def update_py(x: np.ndarray, new: np.ndarray, prev: np.ndarray, free_idx: np.ndarray,
              omega: float, relax: float, chebyshev: bool) -> float:
    """Store the global step's solution ``new`` (n_free, dim) in ``x``; return ``max |change|``.

    Plain (``chebyshev`` False): ``x_free = new``, ``prev`` untouched. Chebyshev (Wang 2015,
    eq. 11): ``x_free <- omega (relax (new - x_free) + x_free - prev_free) + prev_free``
    (each factor skipped when it is 1) and ``prev_free <-`` the old ``x_free``. NaN when a
    value is not finite.
    """
    change = 0.0
    finite = True
    for r in range(free_idx.shape[0]):
        d = update_row(x, prev, free_idx[r], new, r, omega, relax, chebyshev)
        if not np.isfinite(d):
            finite = False
        elif d > change:
            change = d
    return change if finite else np.nan


def update_row(x: np.ndarray, prev: np.ndarray, a: int, new: np.ndarray, r: int, omega: float,
               relax: float, chebyshev: bool) -> float:
    """Store ``new[r]`` in particle ``a`` (as :func:`update_py`); return its largest change.

    NaN when a coordinate's change is not finite.
    """
    change = 0.0
    finite = True
    for c in range(x.shape[1]):
        old = x[a, c]
        value = new[r, c]
        if chebyshev:
            if relax != 1.0:
                value = relax * (value - old) + old
            if omega != 1.0:
                value = omega * (value - prev[a, c]) + prev[a, c]
            prev[a, c] = old
        x[a, c] = value
        d = abs(value - old)
        if not np.isfinite(d):
            finite = False
        elif d > change:
            change = d
    return change if finite else np.nan


def local_rhs_numpy(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                    rest_length: np.ndarray, extra: np.ndarray, base: np.ndarray, h2: float,
                    free_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(jd, rhs)`` of :func:`local_rhs_py` computed with vectorised numpy (a reference)."""
    d = x[i] - x[j]
    length = np.linalg.norm(d, axis=1)
    scale = np.where(length > 0.0, stiffness * rest_length / np.where(length > 0.0, length, 1.0), 0.0)
    p = scale[:, None] * d
    n = x.shape[0]
    jd = np.column_stack([np.bincount(i, p[:, c], n) - np.bincount(j, p[:, c], n)
                          for c in range(x.shape[1])]) + extra
    return jd, base + h2 * jd[free_idx]


def projections(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                rest_length: np.ndarray, out: np.ndarray) -> None:
    """Run :func:`projections_py` compiled: add ``J d`` to ``out`` (n_particles, dim)."""
    compiled(projections_py, "the local step of fast_mass_spring", fastmath=False)(
        x, i, j, stiffness, rest_length, out)


def local_rhs(*args) -> None:
    """Run :func:`local_rhs_py` compiled (same arguments)."""
    compiled(local_rhs_py, "the local step of fast_mass_spring", fastmath=False)(*args)


def update(x: np.ndarray, new: np.ndarray, prev: np.ndarray, free_idx: np.ndarray, omega: float,
           relax: float, chebyshev: bool) -> float:
    """Run :func:`update_py` compiled (same arguments and result)."""
    fast = compiled(update_py, "the update of fast_mass_spring", fastmath=False)
    return fast(x, new, prev, free_idx, float(omega), float(relax), bool(chebyshev))
