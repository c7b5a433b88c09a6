"""Runs of springs: the vectorised loop gives bitwise the forces of the plain loop.

:func:`mslab.effects.spring_batches.segments` cuts each batch into runs (consecutive springs
``(a + s, b + s)``, ``b > a``) and plain segments; :func:`mslab.effects.spring_kernels.spring_batch`
sums a run in three vectorisable loops. The claim checked here is exact: for any springs (runs
of every length, either orientation, zero-length springs, repeated particles, random pairs),
the kernel with runs, rows joined by gap springs (:func:`mslab.effects.spring_batches.gap_springs`),
returns the same force bits as the same kernel told that nothing is a run and given the table
without gap springs (every spring through ``spring_range`` in scene order: the loop the runs
replaced). The dissipated power, summed in eight lanes within a run, differs from the plain
running sum by round-off only: two sums of the same m non-negative terms (and a zero for each
gap spring) differ by at most 2 m' eps times the sum, m' the number of terms.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mslab.effects import Springs
from mslab.effects.spring_batches import (
    MAX_GAP,
    MAX_RUN,
    MIN_RUN,
    SAME_STIFFNESS,
    batches,
    gap_springs,
    run_flags,
    segments,
)
from mslab.effects.spring_kernels import spring_kernel
from mslab.fast.model import _param
from mslab.jit import compiled
from mslab.scenes import generators

pytest.importorskip("numba")


def rows(a: np.ndarray) -> np.ndarray:
    """``a`` (n, dim) on coordinate-major memory, as the stepping loops hand it to kernels (layout "F")."""
    return np.ascontiguousarray(a.T).T


def spring_table(rng: np.random.Generator, n: int, pieces: int) -> tuple[np.ndarray, np.ndarray]:
    """Springs in pieces: rows ``(a + s, a + d + s)`` of random length and sign of ``d``, random pairs."""
    i, j = [], []
    for _ in range(pieces):
        kind = rng.integers(4)
        length = int(rng.choice([1, MIN_RUN - 1, MIN_RUN, MIN_RUN + 5, 3 * MIN_RUN, MAX_RUN + 7]))
        if kind == 3:  # random pairs, repeated particles included
            a, b = rng.integers(0, n, length), rng.integers(0, n, length)
        else:
            d = int(rng.integers(-n // 3, n // 3))
            if kind == 2:
                d = 0  # zero offset: i == j, a spring of one particle
            a0 = int(rng.integers(max(0, -d), n - max(0, d) - length)) if n - abs(d) > length else 0
            a = a0 + np.arange(length)
            if kind == 1:  # rows of a mesh: a few particles skipped now and then (gap springs join them)
                jumps = np.where(rng.random(length) < 0.05, rng.integers(2, MAX_GAP + 3, length), 1)
                a = a0 + np.cumsum(jumps)
                a = a[a < n - max(0, d)]
            b = a + d
            ok = (a >= 0) & (a < n) & (b >= 0) & (b < n)
            a, b = a[ok], b[ok]
        i.append(a)
        j.append(b)
    empty = [np.zeros(0, dtype=np.int64)]
    return np.concatenate(empty + i).astype(np.int64), np.concatenate(empty + j).astype(np.int64)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dim=st.sampled_from([1, 2, 3]), damped=st.booleans(),
       pieces=st.integers(1, 12), parallel=st.booleans(), uniform=st.booleans(), major=st.booleans())
def test_runs_give_the_plain_loops_bits(seed, dim, damped, pieces, parallel, uniform, major):
    """Runs (on coordinate-major memory when ``major``, as in the loops) give the plain loop's bits."""
    rng = np.random.default_rng(seed)
    n = 4 * MAX_RUN
    i, j = spring_table(rng, n, pieces)
    m = i.size
    sizes = {"min_parallel": 64, "per_batch": 256} if parallel else {}
    order, ranges, phases = batches(i, j, n, **sizes)
    i, j = i[order], j[order]
    x = rng.normal(size=(n, dim))
    x[j[: m // 7]] = x[i[: m // 7]]  # some springs of zero length
    v = rng.normal(size=(n, dim))
    k, rest = rng.uniform(1, 100, m), rng.uniform(0.1, 2, m)
    c = rng.uniform(0, 3, m) if damped else np.zeros(m)
    if uniform:  # one stiffness and damping (a mesh's rows), a few springs apart: runs held in registers
        k, c = np.full(m, k[0]), np.full(m, c[0])
        k[:: max(1, m // 3)] = 7.0
    kernel = compiled(spring_kernel)
    plain = (i, j, k, rest, c, int(damped), *segments(i, j, ranges), phases, np.zeros(0, np.int64))
    take, step, ranges_g = gap_springs(i, j, ranges)  # rows joined by gap springs
    ig, jg, kg, cg = i[take] + step, j[take] + step, k[take], c[take]
    bounds, run, batch_segments = segments(ig, jg, ranges_g)
    run = run_flags(bounds, run, kg, cg)
    joined = (ig, jg, kg, rest[take], cg, int(damped), bounds, run, batch_segments, phases,
              np.flatnonzero(step))
    f_runs = rng.normal(size=(n, dim))  # forces already there (gravity): added to, in order
    f_plain = f_runs.copy()
    if major:
        f_runs = rows(f_runs)
    p_runs = kernel(rows(x) if major else x, rows(v) if major else v, f_runs, *[_param(p) for p in joined])
    params = [_param(p) for p in plain]
    params[7] = np.zeros_like(params[7])  # nothing is a run: every spring through spring_range
    p_plain = kernel(x, v, f_plain, *params)
    assert np.array_equal(f_runs, f_plain)
    assert abs(p_runs - p_plain) <= 2 * take.size * np.finfo(float).eps * p_plain
    assert (p_runs == p_plain) or damped and dim == 3  # only a damped run sums in lanes
    assert np.all(np.isfinite(f_runs))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), pieces=st.integers(0, 12), parallel=st.booleans())
def test_segments_partition_each_batch_into_runs_and_plain_stretches(seed, pieces, parallel):
    rng = np.random.default_rng(seed)
    n = 4 * MAX_RUN
    i, j = spring_table(rng, n, pieces)
    sizes = {"min_parallel": 64, "per_batch": 256} if parallel else {}
    order, ranges, phases = batches(i, j, n, **sizes)
    i, j = i[order], j[order]
    bounds, run, batch_segments = segments(i, j, ranges)
    assert bounds[0] == 0 and bounds[-1] == i.size and np.all(np.diff(bounds) > 0)
    assert batch_segments[0] == 0 and batch_segments[-1] == run.size
    for r in range(len(ranges) - 1):  # a batch is whole segments
        assert bounds[batch_segments[r]] == ranges[r] or ranges[r] == ranges[r + 1]
    for s in range(run.size):
        a, b = i[bounds[s]:bounds[s + 1]], j[bounds[s]:bounds[s + 1]]
        if run[s]:  # consecutive springs, one offset, j after i; long runs cut at MAX_RUN
            assert a.size <= MAX_RUN
            assert np.all(np.diff(a) == 1) and np.all(b - a == b[0] - a[0]) and b[0] > a[0]
        else:  # no stretch of MIN_RUN springs that could have been a run is left plain
            longest = streak = 1
            for q in range(1, a.size):
                same = a[q] == a[q - 1] + 1 and b[q] - a[q] == b[q - 1] - a[q - 1]
                streak = streak + 1 if same else 1
                if b[q] > a[q]:
                    longest = max(longest, streak)
            assert longest < MIN_RUN

def test_a_cloth_is_all_runs():
    """The default path reaches the vectorised loop: a 64 x 64 cloth's springs all lie in runs."""
    scene = generators.cloth(64, 64)
    springs = next(e for e in scene.system.effects if isinstance(e, Springs))
    *_, bounds, run, batch_segments, phases, gaps = springs.kernel_params()
    in_runs = int(np.sum(np.diff(bounds)[run != 0]))
    assert in_runs == len(springs.i) + gaps.size
    assert np.all(run & SAME_STIFFNESS)  # each row has one stiffness and damping (issue 38 item 1)


def test_one_stiffness_is_one_bit_pattern():
    """A run has one stiffness and damping only when their bits agree: 0.0 and -0.0 do not.

    (``s - c r / l`` with ``c = -0.0`` and ``0.0`` can differ in the sign of a zero force.)
    Fails on the old code (no ``run_flags``).
    """
    i = np.arange(2 * MIN_RUN, dtype=np.int64)
    j, ranges = i + 1, np.array([0, i.size], dtype=np.int64)
    bounds, run, _ = segments(i, j, ranges)
    k = np.full(i.size, 5.0)
    assert run_flags(bounds, run, k, np.zeros(i.size)).tolist() == [1 | SAME_STIFFNESS]
    mixed = np.zeros(i.size)
    mixed[3] = -0.0
    assert run_flags(bounds, run, k, mixed).tolist() == [1]
    k[-1] = np.nextafter(5.0, 6.0)
    assert run_flags(bounds, run, k, np.zeros(i.size)).tolist() == [1]


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 63, 1000])
def test_lane_sum_is_a_sum(n):
    """Eight lanes plus a tail: the exact sum to round-off (math.fsum), every value counted once."""
    import math

    from mslab.effects.spring_kernels import lane_sum

    values = np.random.default_rng(n).uniform(0, 1, n)
    total = compiled(lane_sum)(values)
    assert abs(total - math.fsum(values)) <= n * np.finfo(float).eps * math.fsum(values)
    ones = np.ones(n)
    assert compiled(lane_sum)(ones) == n  # integers are exact: no value lost or counted twice


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("n", [0, 5, 8, 15, 16, 91, 1000, 4093])
def test_lane_sum_adds_in_its_stated_order(dtype, n):
    """Compiled (the vector lanes of mslab.lanes), the sum is bitwise that of its stated order.

    The reference is written here from the docstring: value s into lane s % 8 in float64, each
    lane in index order, the tail into lane 0, then ((l0 + l1) + (l2 + l3)) + ((l4 + l5) + (l6 +
    l7)), for contiguous arrays (the vector lanes) and strided ones (the scalar loop). Values
    spanning 16 orders of magnitude make any other order round differently (also
    checked: the reversed order differs for the long arrays), and a partial count reads no
    value past it.
    """
    from mslab.effects.spring_kernels import lane_sum
    from mslab.lanes import eight_lanes

    rng = np.random.default_rng(n)
    values = (rng.uniform(0.5, 1, n + 9) * 10.0 ** rng.uniform(-8, 8, n + 9)).astype(dtype)
    lanes = [0.0] * 8
    body = n - n % 8
    for s in range(body):
        lanes[s % 8] += float(values[s])
    body_lanes = tuple(lanes)
    for s in range(body, n):
        lanes[0] += float(values[s])
    l0, l1, l2, l3, l4, l5, l6, l7 = lanes
    expected = ((l0 + l1) + (l2 + l3)) + ((l4 + l5) + (l6 + l7))
    assert compiled(lane_sum)(values, n) == expected
    assert compiled(lane_sum)(np.repeat(values, 2)[::2], n) == expected  # strided: the scalar loop, same sums
    numba = pytest.importorskip("numba")
    vector = numba.njit(lambda v, stop: eight_lanes(v, stop))  # the overload of mslab.lanes
    assert vector(values, body) == eight_lanes(values, body) == body_lanes
    if n >= 1000:
        backwards = 0.0
        for s in range(n - 1, -1, -1):
            backwards += float(values[s])
        assert backwards != expected  # the data can tell one order from another


def cloth_tables(n: int) -> tuple[tuple, tuple]:
    """A cloth's kernel parameters (rows joined by gap springs) and the same springs without them."""
    scene = generators.cloth(n, n, damping=2.0)
    return tables(next(e for e in scene.system.effects if isinstance(e, Springs)))


def tables(springs: Springs) -> tuple[tuple, tuple]:
    """``springs``' kernel parameters (rows joined by gap springs) and the same springs without them."""
    joined = springs.kernel_params()
    order, ranges, phases = batches(springs.i, springs.j, springs.n)
    i, j = springs.i[order], springs.j[order]
    k, c = springs.stiffness[order], springs.damping[order]
    bounds, run, batch_segments = segments(i, j, ranges)
    plain = (i, j, k, springs.rest_length[order], c, joined[5], bounds, run_flags(bounds, run, k, c),
             batch_segments, phases, np.zeros(0, np.int64))
    return joined, plain


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_gap_springs_join_a_cloths_rows_and_exert_nothing(dtype):
    """A 64 x 64 cloth's 256 segments become 6 runs, one per kind of spring; the forces keep their bits.

    (Each kind has at most ``MAX_RUN`` = 4096 springs with its gap springs.) The power keeps its value.

    The gap springs must be left out: the same table with ``gaps`` empty (their forces added
    like a real spring's) changes the forces, so the check can fail.
    """
    joined, plain = cloth_tables(64)
    gaps = joined[10]
    assert gaps.size == 313 and np.diff(joined[6]).size == 6 and np.diff(plain[6]).size == 256
    assert np.diff(joined[6]).max() <= MAX_RUN == 4096
    i, j = joined[0].astype(np.int64), joined[1].astype(np.int64)
    for before in (gaps - 1, gaps + 1):  # each continues a row: (a + s, b + s) between two of its springs
        assert np.all(np.abs(i[gaps] - i[before]) == 1) and np.all(j[gaps] - i[gaps] == j[before] - i[before])
    rng = np.random.default_rng(3)
    x = (generators.cloth(64, 64).state0.x + rng.normal(scale=0.01, size=(4096, 3))).astype(dtype)
    v = rng.normal(size=x.shape).astype(dtype)
    f0 = rng.normal(size=x.shape).astype(dtype)
    kernel = compiled(spring_kernel)
    out = {}
    for name, table in (("joined", joined), ("plain", plain), ("gaps as springs", joined[:10] + (gaps[:0],))):
        f = rows(f0) if name == "joined" else f0.copy()  # the loops' layout against the particles'
        xl, vl = (rows(x), rows(v)) if name == "joined" else (x, v)
        out[name] = f, kernel(xl, vl, f, *[_param(p, dtype) for p in table])
    assert np.array_equal(out["joined"][0], out["plain"][0])
    bound = 2 * joined[0].size * np.finfo(float).eps * out["plain"][1]
    assert abs(out["joined"][1] - out["plain"][1]) <= bound
    assert not np.array_equal(out["gaps as springs"][0], out["plain"][0])


def test_gap_springs_fill_each_batch_up_to_its_last_spring():
    i = np.arange(200, dtype=np.int64)
    i = i[i % 10 != 9]  # rows of 9 springs (a + s, a + s + 1), one particle skipped between rows
    j = i + 1
    take, step, ranges = gap_springs(i, j, np.array([0, 90, 180]))
    assert np.array_equal(take[step == 0], np.arange(i.size))  # every spring, in order
    skipped = np.arange(9, 190, 10)
    assert np.array_equal((i[take] + step)[step > 0], skipped[skipped != 99])  # not after a batch's last
    assert ranges.tolist() == [0, 99, 198]


def touched(i: np.ndarray, j: np.ndarray, first: int, last: int) -> set[int]:
    return set(i[first:last].tolist()) | set(j[first:last].tolist())


def mesh_rows(rng: np.random.Generator, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """A grid's springs listed row by row, each row's kinds (offsets) in a random order, a few
    particles skipped: rows of one offset meet across a row's end (gap springs join them), and
    rows of two offsets meet a particle or two apart (they must not be joined)."""
    n = width * height
    offsets = np.array([1, 2, width - 1, width, width + 1, 2 * width])
    i, j = [np.zeros(0, dtype=np.int64)], [np.zeros(0, dtype=np.int64)]
    for r in range(height):
        for d in rng.permutation(offsets)[: rng.integers(1, offsets.size + 1)]:
            a = r * width + np.flatnonzero(rng.random(width) > 0.05)
            a = a[a + d < n]
            i.append(a)
            j.append(a + d)
    return np.concatenate(i), np.concatenate(j)


def random_tables(rng: np.random.Generator, pieces: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Either :func:`spring_table` or :func:`mesh_rows`, with the number of particles."""
    if pieces % 2:
        n = 4 * MAX_RUN
        return (*spring_table(rng, n, pieces), n)
    width = int(rng.integers(MIN_RUN // 4, 3 * MIN_RUN))
    height = int(rng.integers(20, 80))
    return (*mesh_rows(rng, width, height), width * height)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), pieces=st.integers(1, 12))
def test_a_gap_spring_lies_between_the_springs_it_joins(seed, pieces):
    """What makes gap springs safe in parallel batches: a gap spring's ``i`` lies strictly
    between the ``i`` of the springs before and after it, and its ``j`` between theirs, so
    in their blocks. Rows of two offsets meeting a particle apart are not joined."""
    rng = np.random.default_rng(seed)
    i, j, n = random_tables(rng, pieces)
    order, ranges, _ = batches(i, j, n, min_parallel=64, per_batch=256)
    i, j = i[order], j[order]
    take, step, _ = gap_springs(i, j, ranges)
    gap = np.flatnonzero(step)
    before, after = take[gap], take[gap] + 1  # the real springs around each gap spring
    assert np.all(after < i.size)
    assert np.all((i[before] < i[before] + step[gap]) & (i[before] + step[gap] < i[after]))
    assert np.all((j[before] < j[before] + step[gap]) & (j[before] + step[gap] < j[after]))


def test_rows_of_two_offsets_are_not_joined():
    a = np.arange(0, 20)
    b = np.arange(21, 41)  # one particle skipped; the second row's offset is 1, the first's 10
    i, j = np.concatenate([a, b]), np.concatenate([a + 10, b + 1])
    _, step, _ = gap_springs(i, j, np.array([0, i.size]))
    assert not np.any(step)
    _, step, _ = gap_springs(i, np.concatenate([a + 1, b + 1]), np.array([0, i.size]))  # one offset
    assert step.tolist().count(1) == 1


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), pieces=st.integers(1, 12))
def test_gap_springs_touch_no_particle_of_another_batch_of_their_phase(seed, pieces):
    """The batches of a phase run at once on several threads: with their gap springs (whose
    ``f + 0.0`` reads and writes force entries) they must still share no particle."""
    rng = np.random.default_rng(seed)
    i, j, n = random_tables(rng, pieces)
    order, ranges, phases = batches(i, j, n, min_parallel=64, per_batch=256)
    take, step, ranges_g = gap_springs(i[order], j[order], ranges)
    ig, jg = i[order][take] + step, j[order][take] + step
    for p in range(phases.size - 1):
        seen: set[int] = set()
        for r in range(phases[p], phases[p + 1]):
            mine = touched(ig, jg, ranges_g[r], ranges_g[r + 1])
            assert not mine & seen
            seen |= mine


def test_a_cloth_in_parallel_batches_is_joined_into_a_few_runs():
    """The 300 x 300 cloth's rows, cut by 32 blocks of particles, are joined by gap springs in
    every batch (two phases on all threads): a few runs per batch, no plain segment."""
    springs = next(e for e in generators.cloth(300, 300).system.effects if isinstance(e, Springs))
    i, j, *_, bounds, run, batch_segments, phases, gaps = springs.kernel_params()
    assert phases.tolist() == [0, 16, 32, 33]
    assert gaps.size > 0 and np.all(run > 0)
    assert np.diff(batch_segments).max() <= 6  # one run per kind of spring (pieces of <= MAX_RUN)
    for p in range(phases.size - 1):
        seen: set[int] = set()
        for r in range(phases[p], phases[p + 1]):
            first, last = bounds[batch_segments[r]], bounds[batch_segments[r + 1]]
            mine = touched(i, j, first, last)
            assert not mine & seen
            seen |= mine


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(0, 50), max_size=30), st.integers(-1, 52))
def test_first_at_least_is_searchsorted(values, value):
    from mslab.effects.spring_kernels import first_at_least

    ascending = np.sort(np.array(values, dtype=np.int64))
    expected = int(np.searchsorted(ascending, value))
    assert first_at_least(ascending, value) == expected
    unsigned = max(value, 0)  # (the kernel's indices are uint32)
    found = compiled(first_at_least)(ascending.astype(np.uint32), unsigned)
    assert found == np.searchsorted(ascending, unsigned)


def test_gap_springs_join_rows_only():
    """Springs listed with a stride (ropes of every 4th particle, a ladder's rails) are no rows:
    joining them would make most of the table gap springs (an outside check found 3 per spring)."""
    ropes = np.concatenate([np.arange(r, 4000 - 4, 4) for r in range(4)])  # (p, p + 4), rope by rope
    rails = np.arange(0, 2000, 2)  # (2k, 2k + 2)
    for i, offset in ((ropes, 4), (rails, 2)):
        _, step, _ = gap_springs(i, i + offset, np.array([0, i.size]))
        assert not np.any(step)
    short = np.concatenate([np.arange(10 * r, 10 * r + 7) for r in range(20)])  # rows of 7 < MIN_ROW
    _, step, _ = gap_springs(short, short + 1, np.array([0, short.size]))
    assert not np.any(step)


def test_no_force_entry_starts_as_negative_zero_in_float32():
    """A constant force below float32's range rounds to -0.0; the loops' forces start from +0.0,
    so a gap spring's +0.0 changes no bit (the outside check's 3D ropes under g = -1e-50)."""
    from mslab import fast
    from mslab.scenes import SceneBuilder

    b = SceneBuilder(dim=3)
    for r in range(3):
        for s in range(60):
            b.add_particle([float(s), 2.0 * r, -0.0], mass=1.0)
    b.add_springs([(60 * r + s, 60 * r + s + 1) for r in range(3) for s in range(59)], stiffness=100.0,
                  rest_length=1.0)
    b.add_gravity([0.0, 0.0, -1e-50])
    system = b.build().system
    model = fast.ForceModel(system, np.float32)
    assert not np.any((model.f0 == 0) & np.signbit(model.f0))
    springs = next(e for e in system.effects if isinstance(e, Springs))
    assert springs.kernel_params()[10].size == 2  # the three ropes are one run
    joined, plain = tables(springs)
    x = np.array([[0.9 * s, 2.0 * r, -0.0] for r in range(3) for s in range(60)], np.float32)  # compressed
    v = np.zeros_like(x)
    out = []
    for table in (joined, plain):
        f = model.f0.copy().T  # (coordinate-major, as in the loops)
        compiled(spring_kernel)(rows(x), rows(v), f, *[_param(p, np.float32) for p in table])
        out.append(f.tobytes())
    assert out[0] == out[1]
