"""Conflict-free batches of springs: the springs' force loop on every core, bitwise the same result.

The compiled spring loop scatters: spring ``q`` adds ``+f_q`` to particle ``i`` and ``-f_q`` to
``j``. Two threads that handle springs sharing a particle would race on its force. So the
springs are put in *batches* that run in *phases*: within one phase no two batches touch the
same particle, the batches of a phase run on all threads, and the phases run one after the
other (:func:`mslab.effects.spring_kernels.spring_kernel`).

The batches come from the particle numbering, which mesh generators make local (a cloth is
numbered row by row). The particles are cut into ``B`` contiguous *blocks* of about equal
size; a spring whose ends lie in blocks ``b`` and ``b`` or ``b + 1`` goes to batch ``b``;
batch ``b`` touches blocks ``b`` and ``b + 1`` only, so the even batches are one phase and
the odd batches another. Springs whose ends lie further apart (a block narrower than a bend
spring, a mesh numbered at random) form a last phase of one batch, run on one thread.
Within a batch the springs keep their order in the scene.

Determinism: ``B`` depends on the scene alone (the numbers of particles and springs, and how
many springs lie in runs), never on the
number of threads or the machine; each particle then receives its springs' forces in the
same order whichever thread computes them, so positions are bitwise the same on 1 or 64
threads. (They differ in round-off from a loop over the springs in scene order: another
order of summation; ``tests/test_fast.py`` holds both to the numpy reference.)

Each batch is then cut into *runs* (consecutive springs between consecutive particles, rows of
a mesh) and plain stretches (:func:`segments`): a run's loop touches contiguous memory, so the
compiler vectorises it, with the same sums in the same order. The rows of a mesh are first
joined into longer runs by *gap springs* (:func:`gap_springs`), which exert no force and stay
within their batch's two blocks.

Cost: ``O(n_springs log n_springs)`` once per scene (a stable sort), kept on the effect.
"""

from __future__ import annotations

import numpy as np

#: springs per batch: a batch must outweigh the start of a parallel loop by far (2048
#: springs take about 15 us)
MIN_SPRINGS_PER_BATCH = 2048
#: less work stays in one batch (no parallel loop): waking the sleeping threads costs about
#: 40 us per parallel loop, two per force evaluation, which a smaller step does not repay. The
#: work is counted in springs of the plain loop; a spring in a run (:func:`segments`) counts
#: half, as it takes about half the time. Measured on 2 cores, step time on two threads / one
#: (41 interleaved frames): cloths, all springs in runs, 128 x 128 (97k springs) 1.08, 150 x 150
#: (134k) 1.05, 180 x 180 (193k) 0.86, 300 x 300 (537k) 0.75; before the runs (plain loop)
#: 64 x 64 (24k) 1.4, 128 x 128 0.92 (benchmarks/RESULTS.md, "Runs" and "Threads")
MIN_SPRINGS_PARALLEL = 80_000
#: most blocks of particles; 32 keep two phases of 16 batches busy on up to 16 threads
MAX_BLOCKS = 32


def block_count(n_particles: int, n_springs: int, min_parallel: int = MIN_SPRINGS_PARALLEL,
                per_batch: int = MIN_SPRINGS_PER_BATCH, work: float | None = None) -> int:
    """Return the number of particle blocks ``B`` (1: one batch, no parallel loop).

    One when the ``work`` (default ``n_springs``; :func:`batches` counts a spring in a run as
    half) is below ``min_parallel`` (:data:`MIN_SPRINGS_PARALLEL`); else at least
    ``per_batch`` springs per batch (:data:`MIN_SPRINGS_PER_BATCH`), at most
    :data:`MAX_BLOCKS` blocks, at least 4 particles per block; from the sizes alone (never the
    thread count).
    """
    if (n_springs if work is None else work) < min_parallel:
        return 1
    blocks = min(MAX_BLOCKS, n_springs // per_batch, n_particles // 4)
    return max(1, int(blocks))


def batches(i: np.ndarray, j: np.ndarray, n_particles: int, **sizes: int) -> tuple[np.ndarray, np.ndarray,
                                                                                    np.ndarray]:
    """Return ``(order, ranges, phases)``: the springs in batch order, batch and phase offsets.

    ``order`` permutes the springs (``i[order]`` ...): batch ``r`` is springs
    ``ranges[r]:ranges[r+1]`` of the permuted table, phase ``p`` is batches
    ``phases[p]:phases[p+1]``. No two batches of one phase share a particle. ``sizes``:
    the thresholds of :func:`block_count` (tests use small ones).
    """
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    m = i.size
    bounds, run, _ = segments(i, j, np.array([0, m]))
    in_runs = int(np.sum(np.diff(bounds)[run == 1]))  # springs in runs, in the scene's order
    blocks = block_count(n_particles, m, work=m - in_runs / 2, **sizes)
    if blocks == 1:
        return np.arange(m), np.array([0, m], dtype=np.int64), np.array([0, 1], dtype=np.int64)
    bi = i * blocks // n_particles
    bj = j * blocks // n_particles
    low = np.minimum(bi, bj)
    near = np.abs(bi - bj) <= 1
    # batch key: even batches 0, 2, 4 ..., then odd batches 1, 3 ..., then the far springs
    n_even = (blocks + 1) // 2
    rank = np.where(low % 2 == 0, low // 2, n_even + low // 2)
    key = np.where(near, rank, blocks)
    order = np.argsort(key, kind="stable")
    counts = np.bincount(key, minlength=blocks + 1)
    ranges = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    phases = np.array([0, n_even, blocks, blocks + 1], dtype=np.int64)
    return order, ranges, phases


#: shortest run worth its own vectorised loop (its set-up costs): measured on cloths, rows of
#: 39 springs took 0.94 of the plain loop's time, rows of 49 0.60 (AVX-512, 2026-11-26)
MIN_RUN = 48
#: longest run in one go: its buffers (pair forces and powers, 4 x 8 bytes per spring) stay in a
#: second-level cache of 256 KiB. Fewer, longer runs cost less set-up per evaluation: 4096 took
#: 0.91-0.99 of 1024's time on the 64² and 128² cloths (8 sessions each, benchmarks/RESULTS.md)
MAX_RUN = 4096


def segments(i: np.ndarray, j: np.ndarray, ranges: np.ndarray, min_run: int = MIN_RUN,
             max_run: int = MAX_RUN) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut each batch into *runs* and plain segments; return ``(bounds, run, batch_segments)``.

    A *run* is a stretch of consecutive springs ``(a + s, b + s)``, ``s = 0 .. m-1``, with
    ``b > a`` (a row of structural, shear or bend springs of a mesh generator): its ends are
    consecutive particles, so its loop reads and writes contiguous memory and the compiler
    vectorises it (:func:`mslab.effects.spring_kernels.spring_batch`). Everything else is a
    plain segment, summed spring by spring (:func:`~mslab.effects.spring_kernels.spring_range`).
    Segment ``s`` is springs ``bounds[s]:bounds[s+1]``, a run if ``run[s]``; batch ``r`` is
    segments ``batch_segments[r]:batch_segments[r+1]``. Runs shorter than ``min_run`` are
    plain; longer than ``max_run`` are cut in pieces of equal length. The springs keep their
    order, and so does every particle's sum (``spring_batch`` adds the ``j`` ends first:
    ``b > a``), so the forces are bitwise those of one loop over the batch. Cost
    ``O(n_springs)``, once per scene.
    """
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    ranges = np.asarray(ranges, dtype=np.int64)
    m = i.size
    if m == 0:
        return np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(ranges.size, dtype=np.int64)
    offset = j - i
    new = np.ones(m, dtype=bool)
    new[1:] = (i[1:] != i[:-1] + 1) | (offset[1:] != offset[:-1])
    new[ranges[:-1][ranges[:-1] < m]] = True  # a run never crosses a batch
    start = np.flatnonzero(new)
    length = np.diff(np.append(start, m))
    vector = (length >= min_run) & (offset[start] > 0)
    pieces = -(-length[vector] // max_run)
    size = np.repeat(-(-length[vector] // pieces), pieces)  # equal pieces: none much shorter
    first_piece = np.repeat(np.cumsum(pieces) - pieces, pieces)
    piece_start = np.repeat(start[vector], pieces) + (np.arange(pieces.sum()) - first_piece) * size
    after_run = np.concatenate([[True], vector[:-1]])
    plain_start = start[~vector & (after_run | np.isin(start, ranges))]
    bounds = np.concatenate([piece_start, plain_start])
    run = np.concatenate([np.ones(piece_start.size, np.int64), np.zeros(plain_start.size, np.int64)])
    order = np.argsort(bounds, kind="stable")
    bounds, run = np.append(bounds[order], m), run[order]
    return bounds, run, np.searchsorted(bounds[:-1], ranges).astype(np.int64)


#: most gap springs that join two rows (a mesh's rows of bend springs stop two particles short)
MAX_GAP = 3
#: fewest springs of each of the two rows a gap joins (so gap springs stay a small share:
#: springs listed with a stride, ``(p, p + 4)`` rope by rope, are no rows to join)
MIN_ROW = 8


def gap_springs(i: np.ndarray, j: np.ndarray, ranges: np.ndarray,
                max_gap: int = MAX_GAP) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Join rows of springs into longer runs by *gap springs*; return ``(take, step, ranges)``.

    A mesh generator lists a row's springs ``(a + s, b + s)`` and then the next row's, which
    starts a few particles further on: the run breaks at every row's end, and a 64 x 64 cloth
    is 256 runs, most of them rows of about 63 springs, each paying a run's set-up (a tenth of
    its time, ``benchmarks/RESULTS.md``). Where two consecutive springs of a batch have the same offset
    ``b - a > 0`` and ``i`` jumps by ``2 .. max_gap + 1``, each the end or start of a row of at
    least :data:`MIN_ROW` consecutive springs ``(a + s, b + s)``, the springs between them that the
    mesh does not have (``(a + s, b + s)`` for the skipped ``s``) are inserted as *gap
    springs*: they exert no force. The kernel sets their pair forces to ``+0.0``, which leaves
    every force entry as it is: ``f + 0.0`` and ``f - 0.0`` are ``f`` unless ``f`` is ``-0.0``,
    and no entry is: it starts from the constant forces, formed as ``0.0 + ...`` and made
    ``+0.0`` where they round to a zero (:class:`mslab.fast.ForceModel`), and an IEEE sum or
    difference is ``-0.0`` only where its first operand already is. Their powers are
    ``+0.0`` too (the dissipated power changes by round-off: another order of its sum). The
    rows then form one run (a 64 x 64 cloth: 6 runs instead of 256, 1.3 % gap springs), and
    each particle still receives its springs' forces in the same order: the forces are
    bitwise those of the table without gap springs.

    A batch of a parallel phase gets them too: a gap spring's particles lie between those of the
    two springs it joins (``i`` between their ``i``, ``j`` between their ``j``), so in the blocks
    of its batch (a block is a range of particle indices, :func:`batches`), which no other batch
    of the phase touches (the two springs have one offset ``b - a``: rows of two offsets are not
    joined). A 300 x 300 cloth then has 192 runs instead of 1342 and takes 0.82-0.91 of the
    time (``benchmarks/RESULTS.md``).

    Returns, per spring of the new table, ``take`` (the spring of ``i, j`` it copies: its
    stiffness, rest length and damping; a gap spring copies the spring before it) and ``step``
    (0, or ``u`` for the gap spring ``(i + u, j + u)`` of that spring), and the new batch
    offsets. Cost ``O(n_springs)``, once per scene.
    """
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    ranges = np.asarray(ranges, dtype=np.int64)
    m = i.size
    gaps = np.zeros(m, dtype=np.int64)  # gap springs after spring q
    if m > 1:
        jump = i[1:] - i[:-1]
        offset = j - i
        same = offset[1:] == offset[:-1]
        starts = np.ones(m, dtype=bool)  # a row of consecutive springs (a + s, b + s) starts here
        starts[1:] = ~(same & (jump == 1))
        starts[ranges[:-1][ranges[:-1] < m]] = True
        row = np.cumsum(starts) - 1
        length = np.bincount(row)[row]  # the length of each spring's row
        fill = same & (offset[:-1] > 0) & (jump >= 2) & (jump <= max_gap + 1)
        fill &= (length[:-1] >= MIN_ROW) & (length[1:] >= MIN_ROW)
        last = np.zeros(m, dtype=bool)  # the last spring of a batch: no gap after it
        last[np.clip(ranges[1:] - 1, 0, m - 1)] = True
        fill &= ~last[:-1]
        gaps[:-1] = np.where(fill, jump - 1, 0)
    take = np.repeat(np.arange(m), 1 + gaps)
    step = np.arange(take.size) - np.repeat(np.cumsum(1 + gaps) - (1 + gaps), 1 + gaps)
    before = np.concatenate([[0], np.cumsum(gaps)])  # gap springs before spring q
    return take, step, ranges + before[np.minimum(ranges, m)]


#: bits of a segment's ``run`` entry (:func:`run_flags`): a run; a run whose springs have one
#: stiffness and one damping
RUN, SAME_STIFFNESS = 1, 2


def run_flags(bounds: np.ndarray, run: np.ndarray, stiffness: np.ndarray, damping: np.ndarray) -> np.ndarray:
    """Return ``run`` with the bit :data:`SAME_STIFFNESS` set on the runs that have one stiffness and damping.

    Every row of a mesh generator's cloth has; :func:`mslab.effects.spring_kernels.spring_batch`
    then holds the two values in registers instead of loading them spring by spring. "One
    value" is bitwise (``0.0`` and ``-0.0`` differ), so the forces are bitwise those of the
    per-spring values. (Rest lengths computed from a mesh's positions differ in their last
    bits from spring to spring: they stay per spring.) Cost ``O(n_springs)``, once per scene.
    """
    flags = np.asarray(run, dtype=np.int64).copy()
    starts = np.asarray(bounds[:-1], dtype=np.int64)
    if starts.size == 0:
        return flags

    def same(values: np.ndarray) -> np.ndarray:
        bits = np.ascontiguousarray(values, dtype=np.float64).view(np.int64)
        return np.minimum.reduceat(bits, starts) == np.maximum.reduceat(bits, starts)

    flags[(flags != 0) & same(stiffness) & same(damping)] |= SAME_STIFFNESS
    return flags
