"""Gap springs in the batches of parallel phases, against none there, in one process (issue 38).

Usage::

    .venv/bin/python benchmarks/gap_batches.py [--repeats 11] [--sessions 4] [--sizes 300]

Until 2026-11-29 :func:`mslab.effects.spring_batches.gap_springs` joined rows only in a batch
alone in its phase, so a cloth of more than ``MIN_SPRINGS_PARALLEL`` springs kept a run per
row (the 300 x 300 cloth: 1342 runs, each paying a run's set-up). Now every batch gets them.
The old rule is rebuilt here by dropping the gap springs of batches in phases of several
batches (a wrapper of ``gap_springs`` while the old sessions build their tables).

For the frame loop's cloth (``benchmarks/frame_loop.py``: k = 1000, c = 10, symplectic Euler
at dt = 1/960), per precision and thread count (1 and 2): ``--sessions`` sessions of each
rule (a session's time depends on where its arrays land, so several), the end states of an
old and a new session compared bitwise after a warm-up frame, then interleaved repeats of
``advance(16)`` on every session in wall-clock time. Reported: ns per spring-step (median over
sessions, then over repeats), new / old (median, min-max of the per-repeat ratios), the runs
of either table, the load average. Written to ``benchmarks/gap_batches.json``. Nothing here
is a test.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.frame_loop import DT, frame_cloth  # noqa: E402
from benchmarks.session_ab import compare_ways, main  # noqa: E402


def without_parallel_gaps(gap_springs):
    """``gap_springs`` under the old rule: no gap spring in a batch of a phase of several batches."""
    def old(i, j, ranges, *args, **kwargs):
        take, step, new_ranges = gap_springs(i, j, ranges, *args, **kwargs)
        blocks = ranges.size - 2  # B blocks: batches 0 .. B-1 in two phases, then the far batch
        parallel = np.zeros(ranges.size - 1, dtype=bool)
        if blocks > 1:  # (one block: a single batch, alone; see spring_batches.batches)
            parallel[: (blocks + 1) // 2] = (blocks + 1) // 2 > 1
            parallel[(blocks + 1) // 2: blocks] = blocks // 2 > 1
        batch = np.searchsorted(new_ranges, np.arange(take.size), side="right") - 1
        keep = (step == 0) | ~parallel[batch]
        kept = np.concatenate([[0], np.cumsum(keep)])
        return take[keep], step[keep], kept[new_ranges]

    return old


def compare(n: int, dtype: str, threads: int, repeats: int, sessions: int) -> dict:
    import mslab
    import mslab.effects.springs as springs_module
    from mslab.effects import Springs

    new_rule = springs_module.gap_springs
    runs = {}

    def make(rule: str):
        springs_module.gap_springs = without_parallel_gaps(new_rule) if rule == "old" else new_rule
        try:
            sim = mslab.Simulation(frame_cloth(n), "symplectic_euler", dt=DT, backend="numba",
                                   threads=threads, dtype=dtype, check_stability=False)
        finally:
            springs_module.gap_springs = new_rule
        springs = next(e for e in sim.system.effects if isinstance(e, Springs))
        runs[rule] = int(np.count_nonzero(springs.kernel_params()[7]))
        return sim

    m = next(e for e in frame_cloth(n).system.effects if isinstance(e, Springs)).i.size
    return {**compare_ways(make, ("old", "new"), m, repeats, sessions), "runs": runs}


if __name__ == "__main__":
    main(__doc__.splitlines()[0], compare, ("old", "new"), HERE / "gap_batches.json")
