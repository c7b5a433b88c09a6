"""The springs' kernel with the kick pass fused into its second phase, against the two apart (issue 38).

Usage::

    .venv/bin/python benchmarks/fused_kick.py [--repeats 11] [--sessions 4] [--sizes 300]

``mslab.effects.spring_kick.spring_kernel_kick`` kicks each block of particles in the springs'
second parallel phase, as soon as its forces are complete: a step of symplectic Euler on a
cloth above ``MIN_SPRINGS_PARALLEL`` launches the threads twice instead of three times. The
old way is ``mslab.fast.compose.FUSED_KICK = False`` while the old sessions are made.

For the frame loop's cloth (``benchmarks/frame_loop.py``: k = 1000, c = 10, symplectic Euler at
dt = 1/960), per precision and thread count (1 and 2): ``--sessions`` sessions of each way, the
end states of a fused and an apart session compared bitwise after a warm-up frame, then
interleaved repeats of ``advance(16)`` on every session in wall-clock time. Reported: ns per
spring-step (median over sessions, then over repeats), fused / apart (median, min-max of the
per-repeat ratios), the load average. Written to ``benchmarks/fused_kick.json``. Nothing here is
a test.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.frame_loop import DT, frame_cloth  # noqa: E402
from benchmarks.session_ab import compare_ways, main  # noqa: E402


def compare(n: int, dtype: str, threads: int, repeats: int, sessions: int) -> dict:
    import mslab
    from mslab.effects import Springs
    from mslab.fast import compose

    def make(way: str):
        compose.FUSED_KICK = way == "fused"
        try:
            return mslab.Simulation(frame_cloth(n), "symplectic_euler", dt=DT, backend="numba",
                                    threads=threads, dtype=dtype, check_stability=False)
        finally:
            compose.FUSED_KICK = True

    m = next(e for e in frame_cloth(n).system.effects if isinstance(e, Springs)).i.size
    return compare_ways(make, ("apart", "fused"), m, repeats, sessions)


if __name__ == "__main__":
    main(__doc__.splitlines()[0], compare, ("apart", "fused"), HERE / "fused_kick.json")
