"""Newton's matrix on the free degrees of freedom, assembled on a sparsity pattern kept between calls.

Newton's matrix of an implicit Euler-like stage, scaled by the masses and restricted to the
free dofs, is ``A = M - c^2 K - c D`` (see :mod:`mslab.integrators.newton.linear`). Its sparsity
pattern is that of the force Jacobians, which stays the same from one Newton iteration
and one step to the next while the scene's contacts do not change. :class:`FreePattern`
computes, once per pattern, where every entry of ``c^2 K + c D`` lands in ``A`` (rows and
columns of pinned dofs dropped, the mass diagonal added, duplicates summed), the
transposition permutation (for the symmetry test) and the lower triangle in compressed
column order (what CHOLMOD reads). Every later assembly is one ``np.bincount``.

CHOLMOD (through cvxopt) splits a Cholesky factorisation into a symbolic analysis
(fill-reducing ordering, elimination tree, supernodes), which depends on the pattern only,
and the numeric factorisation. The pattern keeps one CHOLMOD factor object and refactors it
numerically for every new matrix, so the symbolic analysis runs once per pattern (measured
about a quarter of a factorisation on a 100 x 100 cloth). A refactorisation overwrites the
numbers of the previous one: :attr:`FreePattern.owner` names the one factorisation whose
numbers the object holds, and a stale one refuses to solve.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp


def cholmod_module() -> Any:
    """Return cvxopt (with its CHOLMOD binding), or None when it is not installed."""
    try:
        import cvxopt
        import cvxopt.cholmod
    except ImportError:  # scipy only: SuperLU in symmetric mode
        return None
    return cvxopt


class FreePattern:
    """Where the entries of the Jacobian terms (all dofs, CSR) go in ``A`` (free dofs, CSR).

    Parameters
    ----------
    parts : list of scipy.sparse.csr_matrix
        The terms whose sum, scaled, is ``c^2 K + c D`` (e.g. each effect's ``K`` and ``D``);
        duplicates and unsorted indices are allowed. Their patterns are recorded.
    free : ndarray of bool, shape (n_dofs,)
        The free degrees of freedom.
    """

    def __init__(self, parts: list, free: np.ndarray):
        import scipy.sparse as sp

        self.patterns = [(p.indptr.copy(), p.indices.copy()) for p in parts]
        n_all = free.size
        none = [np.zeros(0, dtype=np.int64)]  # (no terms at all: A = M)
        rows = np.concatenate(none + [np.repeat(np.arange(n_all), np.diff(p.indptr)) for p in parts])
        cols = np.concatenate(none + [p.indices for p in parts])
        self.rows_in = rows  # row of every entry of the concatenated terms (row sums)
        new = np.cumsum(free) - 1
        m = int(np.count_nonzero(free))
        self.size = m
        keep = free[rows] & free[cols]
        self.source = np.flatnonzero(keep)  # entries of the terms that enter A
        keys = np.concatenate([new[rows[keep]].astype(np.int64) * m + new[cols[keep]],
                               np.arange(m, dtype=np.int64) * (m + 1)])  # + the mass diagonal
        unique, slot = np.unique(keys, return_inverse=True)
        self.keys = unique  # row * size + column of every entry of A, sorted (CSR order)
        self.slot = slot[: self.source.size]  # slot in A.data of each kept entry
        self.diagonal = slot[self.source.size:]  # slot of A's diagonal entries
        r, c = unique // m, unique % m
        self.indices = c.astype(np.int32)
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=m))]).astype(np.int32)
        # transposition: the slot of (c, r) for every slot (r, c), -1 where (c, r) is no entry
        where = np.minimum(np.searchsorted(unique, c * m + r), unique.size - 1)
        self.transpose = np.where(unique[where] == c * m + r, where, -1)
        self.structurally_symmetric = bool(np.all(self.transpose >= 0))
        # the lower triangle in compressed-column order (CHOLMOD's input)
        lower = np.flatnonzero(r >= c)
        self.lower = lower[np.lexsort((r[lower], c[lower]))]
        self._lower_rows, self._lower_cols = r[self.lower], c[self.lower]
        self._sp = sp
        self._cvx: Any = None  # cvxopt spmatrix of the lower triangle, values set per matrix
        self._symbolic: Any = None  # CHOLMOD factor object (symbolic analysis, then numbers)
        self.owner: object | None = None  # the factorisation whose numbers _symbolic holds

    def matches(self, parts: list) -> bool:
        """Tell whether the terms have the recorded patterns."""
        return len(parts) == len(self.patterns) and all(
            p.indptr.size == ptr.size and p.indices.size == ind.size
            and np.array_equal(p.indptr, ptr) and np.array_equal(p.indices, ind)
            for p, (ptr, ind) in zip(parts, self.patterns, strict=True))

    def assemble(self, lin_data: np.ndarray, mass_free: np.ndarray) -> sp.csr_matrix:
        """Return ``A = diag(mass_free) - lin`` on the free dofs (CSR, on this pattern).

        ``lin_data``: the concatenated values of the (scaled) terms, in the order of ``parts``.
        """
        data = np.bincount(self.slot, weights=-lin_data[self.source], minlength=self.indices.size)
        data = data.astype(float, copy=False)  # (no weights at all: bincount gives integers)
        data[self.diagonal] += mass_free
        return self.matrix(data)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """Return the CSR matrix with these values on the pattern."""
        A = self._sp.csr_matrix((data, self.indices, self.indptr), shape=(self.size, self.size))
        A.has_canonical_format = True
        return A

    def symmetric(self, data: np.ndarray) -> bool:
        """Tell whether the matrix with values ``data`` equals its transpose to round-off."""
        if not self.structurally_symmetric:
            return False
        size = float(np.abs(data).max()) if data.size else 0.0
        return bool(np.abs(data - data[self.transpose]).max(initial=0.0) <= 1e-12 * max(size, 1e-300))

    def cholmod(self, owner: object, data: np.ndarray) -> Any:
        """Factor the matrix with values ``data`` by CHOLMOD; return the factor, or None if not definite.

        The symbolic analysis is done on the first call only; ``owner`` becomes the
        factorisation whose numbers the returned object holds.
        """
        cvxopt = cholmod_module()
        if self._cvx is None:
            self._cvx = cvxopt.spmatrix(data[self.lower], self._lower_rows.astype(np.int64),
                                        self._lower_cols.astype(np.int64), (self.size, self.size))
            # cvxopt keeps the entries in compressed-column order: the order of self.lower
            assert np.array_equal(np.asarray(self._cvx.I).ravel(), self._lower_rows)
            self._symbolic = cvxopt.cholmod.symbolic(self._cvx, uplo="L")
        else:
            self._cvx.V = cvxopt.matrix(data[self.lower])
        self.owner = owner
        try:
            cvxopt.cholmod.numeric(self._cvx, self._symbolic)
        except ArithmeticError:  # not positive definite
            self.owner = None
            return None
        return self._symbolic


def cholmod_solve(F: Any, b: np.ndarray) -> np.ndarray:
    """``A^-1 b`` with CHOLMOD's factors (``b`` of shape (n,) or (n, k))."""
    import cvxopt
    import cvxopt.cholmod

    B = cvxopt.matrix(np.asfortranarray(b, dtype=float).reshape(b.shape[0], -1))
    cvxopt.cholmod.solve(F, B)
    return np.array(B).reshape(b.shape)


def one_shot_pattern(A: sp.spmatrix) -> tuple[FreePattern, np.ndarray]:
    """Return a pattern and the values of a matrix ``A`` met once (all dofs free, no mass added)."""
    import scipy.sparse as sp

    lin = sp.csr_matrix(-A)
    pattern = FreePattern([lin], np.ones(A.shape[0], dtype=bool))
    data = np.bincount(pattern.slot, weights=-lin.data[pattern.source], minlength=pattern.indices.size)
    return pattern, data.astype(float, copy=False)


def is_symmetric(A: sp.spmatrix | np.ndarray) -> bool:
    """Return whether ``A`` equals its transpose to round-off (friction makes it not)."""
    import scipy.sparse as sp

    diff = A - A.T
    size = abs(A).max() if sp.issparse(A) else np.abs(A).max()
    worst = abs(diff).max() if sp.issparse(diff) else np.abs(diff).max()
    return bool(worst <= 1e-12 * max(float(size), 1e-300))


def newton_matrix(K: sp.spmatrix, D: sp.spmatrix | None, mass_dofs: np.ndarray, free: np.ndarray,
                  c: float) -> sp.csc_matrix:
    """Return ``A = M - c^2 K - c D`` on the free dofs (CSC); ``D`` may be None."""
    import scipy.sparse as sp

    lin = K * (c * c) if D is None else K * (c * c) + D * c
    lin = lin.tocsr()[free][:, free]
    return (sp.diags(mass_dofs[free]) - lin).tocsc()
