"""The kept L D L^T solves on every core (mslab.integrators.newton.tree_solve).

Truth from outside: dense LAPACK solves and backward-error bounds (a Cholesky solve is
backward stable: ``|A x - b| <= c n eps |A| |x|`` entry by entry), and a plain one-thread
sweep written here from the exported factors: the threaded solves must give its bits for
any split of the elimination tree and any thread count.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from mslab.integrators.newton import tree_solve
from mslab.integrators.newton.tree_solve import TreeSolve, cholmod_ldlt, deal_subtrees, tree_factor
from mslab.system import Counters

pytest.importorskip("cvxopt")


def mesh_matrix(rows: int, cols: int, seed: int, reach: int = 2, shuffle: bool = True) -> sp.csc_matrix:
    """A cloth-like SPD matrix: masses + the weighted Laplacian of a grid, neighbours ``reach`` apart."""
    rng = np.random.default_rng(seed)
    n = rows * cols
    r, c = np.divmod(np.arange(n), cols)
    pairs = []
    for dr in range(reach + 1):
        for dc in range(-reach, reach + 1):
            if (dr == 0 and dc <= 0) or abs(dr) + abs(dc) > reach:
                continue
            ok = (r + dr < rows) & (c + dc >= 0) & (c + dc < cols)
            pairs.append(np.c_[np.flatnonzero(ok), (r[ok] + dr) * cols + c[ok] + dc])
    i, j = np.concatenate(pairs).T if pairs else (np.zeros(0, int), np.zeros(0, int))
    if shuffle:  # a mesh numbered in no particular order
        perm = rng.permutation(n)
        i, j = perm[i], perm[j]
    k = rng.uniform(0.5, 2.0, i.size)
    lap = sp.coo_matrix((np.r_[k, k, -k, -k], (np.r_[i, j, i, j], np.r_[i, j, j, i])), shape=(n, n))
    return (sp.diags(rng.uniform(0.01, 0.1, n)) + lap).tocsc()


def plain_sweep(perm: np.ndarray, L: sp.csc_matrix, first: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A^-1 b`` from ``A[perm][:, perm] = L D L^T`` on one thread, supernode by supernode (the definition).

    ``first``: the supernodes' first columns. Forward: each supernode's triangle (row by row,
    columns increasing), then each row ``r`` below gets ``y[r] -= sum_m L[r, c+m] y[c+m]``
    (the sum from 0, ``m`` increasing). Backward, supernodes decreasing: ``acc[m] = sum_i
    L[R_i, c+m] x[R_i]`` (from 0, ``i`` increasing), then from the last column ``x = y / D -
    acc - sum_b L[c+b, c+a] x[c+b]`` (``b`` increasing). Numpy vectors of the right-hand
    sides: the same IEEE operations as the compiled loops' scalars.
    """
    n = L.shape[0]
    dense = L.toarray()
    y = b[perm].astype(float).copy()
    bounds = list(zip(first, [*first[1:], n], strict=True))
    below = {}
    for c, end in bounds:
        below[c] = [r for r in range(end, n) if dense[r, c] != 0.0 or (L[:, c].indices == r).any()]
        for a in range(c + 1, end):
            for bb in range(c, a):
                y[a] = y[a] - dense[a, bb] * y[bb]
        for r in below[c]:
            v = np.zeros(b.shape[1])
            for m in range(c, end):
                v = v + dense[r, m] * y[m]
            y[r] = y[r] - v
    for c, end in reversed(bounds):
        acc = {m: np.zeros(b.shape[1]) for m in range(c, end)}
        for r in below[c]:
            for m in range(c, end):
                acc[m] = acc[m] + dense[r, m] * y[r]
        for a in range(end - 1, c - 1, -1):
            s = y[a] / dense[a, a] - acc[a]
            for bb in range(a + 1, end):
                s = s - dense[bb, a] * y[bb]
            y[a] = s
    out = np.empty_like(y)
    out[perm] = y
    return out


def split_for(A: sp.spmatrix, bins: int, monkeypatch: pytest.MonkeyPatch) -> TreeSolve:
    monkeypatch.setattr(tree_solve, "MIN_PARALLEL_ENTRIES", 0)  # split even small matrices
    perm, L = cholmod_ldlt(A)
    return TreeSolve(A, perm, L, bins=bins)


@pytest.mark.parametrize("simplicial", [True, False])  # CHOLMOD's L D L^T, then its (default) L L^T
def test_factors_are_a_factorisation_of_the_matrix(simplicial, monkeypatch):
    import cvxopt.cholmod

    if simplicial:
        monkeypatch.setitem(cvxopt.cholmod.options, "supernodal", 0)
    A = mesh_matrix(40, 43, 0)
    perm, L = cholmod_ldlt(A)
    D = L.diagonal()
    unit = L - sp.diags(D) + sp.eye(A.shape[0])
    assert np.array_equal(np.sort(perm), np.arange(A.shape[0]))
    product = (unit @ sp.diags(D) @ unit.T).toarray()
    assert np.abs(product - A[perm][:, perm].toarray()).max() <= 1e-13 * abs(A).max()


@settings(max_examples=25, deadline=None)
@given(rows=st.integers(1, 14), cols=st.integers(2, 14), seed=st.integers(0, 10_000),
       reach=st.integers(1, 3), bins=st.integers(1, 5), k=st.integers(1, 7))
def test_solves_to_the_backward_error_of_cholesky(rows, cols, seed, reach, bins, k):
    A = mesh_matrix(rows, cols, seed, reach)
    with pytest.MonkeyPatch.context() as mp:
        tree = split_for(A, bins, mp)
    b = np.random.default_rng(seed).standard_normal((A.shape[0], k))
    x = tree.solve(b)
    n = A.shape[0]
    bound = 10 * n * np.finfo(float).eps * (abs(A) @ np.abs(x) + np.abs(b))
    assert np.all(np.abs(A @ x - b) <= bound)
    dense = np.linalg.solve(A.toarray(), b)
    cond = np.linalg.cond(A.toarray())
    assert np.abs(x - dense).max() <= 10 * n * cond * np.finfo(float).eps * np.abs(dense).max()


@settings(max_examples=20, deadline=None)
@given(rows=st.integers(2, 12), cols=st.integers(2, 12), seed=st.integers(0, 10_000),
       reach=st.integers(1, 3))
def test_every_split_gives_the_bits_of_the_plain_sweep(rows, cols, seed, reach):
    A = mesh_matrix(rows, cols, seed, reach)
    b = np.random.default_rng(seed + 1).standard_normal((A.shape[0], 3))
    with pytest.MonkeyPatch.context() as mp:
        trees = [split_for(A, bins, mp) for bins in (1, 2, 3, 4, 7)]
    plain = plain_sweep(trees[0].perm, cholmod_ldlt(A)[1], trees[0].supernodes.sn[:, 0], b)
    for tree in trees:
        assert np.array_equal(tree.solve(b), plain)


def test_thread_count_does_not_change_the_bits():
    from mslab.jit import numba, threads

    A = mesh_matrix(60, 60, 3)  # about 130k entries in L: split among threads
    tree = tree_factor(A, Counters(), threads=2)
    assert tree.bins == 2 and tree.top.size < A.shape[0] // 10
    b = np.random.default_rng(0).standard_normal((A.shape[0], 3))
    with threads(1):
        one = tree.solve(b)
    with threads(numba().config.NUMBA_NUM_THREADS):
        many = tree.solve(b)
    assert np.array_equal(one, many)


def test_columns_are_solved_independently():
    A = mesh_matrix(9, 11, 5)
    tree = tree_factor(A, Counters())
    b = np.random.default_rng(2).standard_normal((A.shape[0], 5))
    whole = tree.solve(b)
    for m in range(5):
        alone = tree.solve(b[:, m])
        assert alone.shape == (A.shape[0],)
        assert np.array_equal(alone, whole[:, m])


def test_the_deal_keeps_subtrees_whole_and_balanced():
    A = mesh_matrix(40, 40, 1)
    perm, L = cholmod_ldlt(A)
    strict = sp.tril(L, -1, format="csc")
    n = A.shape[0]
    parent = np.full(n, -1)
    has = np.diff(strict.indptr) > 0
    parent[has] = strict.indices[strict.indptr[:-1][has]]
    work = np.ones(n)
    owner = deal_subtrees(parent, work, 2)
    for c in range(n):
        p = parent[c]
        if p >= 0 and owner[c] < 0:
            assert owner[p] < 0  # the top is closed upwards
        if p >= 0 and owner[p] >= 0:
            assert owner[c] == owner[p]  # a dealt subtree is whole
    loads = np.bincount(owner[owner >= 0], minlength=2)
    assert loads.max() <= tree_solve.BALANCE * loads.sum() / 2
    assert np.count_nonzero(owner < 0) < n // 10


def test_not_positive_definite_gives_none():
    A = mesh_matrix(6, 6, 0) - sp.eye(36) * 10.0
    assert tree_factor(A.tocsc(), Counters()) is None


def test_without_pymetis_cholmod_orders(monkeypatch):
    A = mesh_matrix(20, 20, 4)
    b = np.random.default_rng(1).standard_normal((A.shape[0], 3))
    with_metis = tree_factor(A, Counters()).solve(b)
    monkeypatch.setattr(tree_solve, "nested_dissection", lambda A: None)
    amd = tree_factor(A, Counters())
    assert np.abs(amd.solve(b) - with_metis).max() <= 1e-10 * np.abs(with_metis).max()


def test_fast_mass_spring_steps_with_the_tree_solves(monkeypatch):
    """A cloth above DENSE_MAX unknowns steps with TreeSolve: Factor's step to round-off."""
    from test_implicit_cloth import scaled_cloth

    import mslab
    from mslab.integrators.families import local_global

    scene = scaled_cloth(24, drag_rate=1.0)  # 576 particles, 552 free: above DENSE_MAX
    s = scene.system
    fms = mslab.get_method("fast_mass_spring")
    local_global._CACHE.pop(s, None)
    tree_step = fms.step(s, scene.state0, 1 / 30)
    assert isinstance(local_global.global_step(s, 1 / 30).factor, TreeSolve)
    local_global._CACHE.pop(s, None)
    monkeypatch.setattr(local_global, "tree_factor", lambda A, counters: None)
    factor_step = fms.step(s, scene.state0, 1 / 30)
    assert not isinstance(local_global.global_step(s, 1 / 30).factor, TreeSolve)
    # two backward-stable solves of Q differ by up to about cond(Q) eps |x| each; ten iterations
    Q = local_global.global_step(s, 1 / 30).factor.A
    bound = 10 * 10 * np.linalg.cond(Q.toarray()) * np.finfo(float).eps * np.abs(tree_step.x).max()
    assert np.abs(tree_step.x - factor_step.x).max() <= bound
    assert bound < 1e-10  # a bound that still says something


def test_bad_right_sides_are_refused():
    tree = tree_factor(mesh_matrix(6, 7, 0), Counters())
    for wrong in (np.ones(41), np.ones(43), np.ones((43, 3)), np.ones((42, 2, 2))):
        with pytest.raises(ValueError, match="42 rows"):
            tree.solve(wrong)
    with pytest.raises(TypeError, match="complex"):
        tree.solve(np.ones(42) * 1j)


def test_not_symmetric_or_empty_gives_none():
    A = mesh_matrix(6, 6, 0).tolil()
    A[0, 5] += 0.5  # one entry above the diagonal without its mirror
    assert tree_factor(A.tocsc(), Counters()) is None
    assert tree_factor(sp.csc_matrix((0, 0)), Counters()) is None


def test_more_threads_than_numba_has_are_clipped(monkeypatch):
    from mslab.jit import numba

    monkeypatch.setenv("MSLAB_THREADS", "64")
    assert tree_solve.bins_for(None) == min(64, numba().config.NUMBA_NUM_THREADS)
    assert tree_solve.bins_for(1) == 1
