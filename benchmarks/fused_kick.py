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

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.float32 import _ratio  # noqa: E402
from benchmarks.frame_loop import DT, SUBSTEPS, frame_cloth  # noqa: E402
from benchmarks.suite import machine  # noqa: E402


def compare(n: int, dtype: str, threads: int, repeats: int, sessions: int) -> dict:
    import mslab
    from mslab.effects import Springs
    from mslab.fast import compose

    sims: dict[str, list] = {"apart": [], "fused": []}
    for _ in range(sessions):
        for way in sims:
            compose.FUSED_KICK = way == "fused"
            try:
                sim = mslab.Simulation(frame_cloth(n), "symplectic_euler", dt=DT, backend="numba",
                                       threads=threads, dtype=dtype, check_stability=False)
                sim.advance(SUBSTEPS)
            finally:
                compose.FUSED_KICK = True
            sims[way].append(sim)
    m = next(e for e in frame_cloth(n).system.effects if isinstance(e, Springs)).i.size
    old, new = sims["apart"][0].state, sims["fused"][0].state
    same = all(np.asarray(getattr(old, k)).tobytes() == np.asarray(getattr(new, k)).tobytes()
               for k in ("x", "v"))
    number = max(1, int(0.02 * 3e8 / (m * SUBSTEPS)))
    per = {(way, q): [] for way in sims for q in range(sessions)}
    load_before = os.getloadavg()
    for _ in range(repeats):
        for (way, q), times in per.items():
            sim = sims[way][q]
            t = time.perf_counter()
            for _ in range(number):
                sim.advance(SUBSTEPS)
            times.append((time.perf_counter() - t) / number / SUBSTEPS / m * 1e9)
    times = {way: [statistics.median(per[way, q][t] for q in range(sessions)) for t in range(repeats)]
             for way in sims}
    return {"n": n, "dtype": dtype, "threads": threads, "springs": m, "bitwise_same": same,
            "sessions": sessions, "repeats": repeats,
            "ns_per_spring_step": {way: statistics.median(t) for way, t in times.items()},
            "fused_over_apart": _ratio(times["fused"], times["apart"]),
            "load_average_before": load_before, "load_average_after": os.getloadavg()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=11)
    parser.add_argument("--sessions", type=int, default=4)
    parser.add_argument("--sizes", type=int, nargs="+", default=[300])
    args = parser.parse_args()
    rows = []
    for n in args.sizes:
        for threads in (1, 2):
            for dtype in ("float32", "float64"):
                row = compare(n, dtype, threads, args.repeats, args.sessions)
                rows.append(row)
                ns, r = row["ns_per_spring_step"], row["fused_over_apart"]
                load = row["load_average_before"][0], row["load_average_after"][0]
                print(f"{n}² {dtype} {threads} thread(s): bitwise same {row['bitwise_same']}; ns/spring-step "
                      f"apart {ns['apart']:.3f} fused {ns['fused']:.3f}; fused/apart {r['median']:.3f} "
                      f"({r['min']:.3f}-{r['max']:.3f}); load {load[0]:.2f}-{load[1]:.2f}", flush=True)
    doc = {"machine": machine(), "rows": rows}
    (HERE / "fused_kick.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
