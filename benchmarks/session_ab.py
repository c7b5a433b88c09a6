"""Two ways of making a session, timed over several sessions each in one process (issue 38's A/B runs).

A session's time moves by up to 1.5x with where its arrays land (``benchmarks/RESULTS.md``), so
each way gets several sessions, made alternately; a repeat's time of a way is the median of its
sessions'. Used by ``gap_batches.py`` and ``fused_kick.py``. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.float32 import _ratio
from benchmarks.frame_loop import SUBSTEPS
from benchmarks.suite import machine


def compare_ways(make: Callable[[str], Any], ways: tuple[str, str], m: int, repeats: int,
                 sessions: int) -> dict:
    """``sessions`` sessions per way (``make(way)``), each advanced a frame; the first of each way
    compared bitwise (``x`` and ``v``); then ``repeats`` interleaved rounds timing ``advance(16)``
    of every session in wall-clock time. Returns the medians in ns per spring-step (``m``
    springs), the ratio second way / first (median, min, max of the rounds) and the load."""
    sims: dict[str, list] = {way: [] for way in ways}
    for _ in range(sessions):
        for way in ways:
            sim = make(way)
            sim.advance(SUBSTEPS)
            sims[way].append(sim)
    a, b = (sims[way][0].state for way in ways)
    same = all(np.asarray(getattr(a, k)).tobytes() == np.asarray(getattr(b, k)).tobytes() for k in ("x", "v"))
    number = max(1, int(0.02 * 3e8 / (m * SUBSTEPS)))
    per: dict[tuple[str, int], list[float]] = {(way, q): [] for way in ways for q in range(sessions)}
    load_before = os.getloadavg()
    for _ in range(repeats):
        for (way, q), times in per.items():
            sim = sims[way][q]
            t = time.perf_counter()
            for _ in range(number):
                sim.advance(SUBSTEPS)
            times.append((time.perf_counter() - t) / number / SUBSTEPS / m * 1e9)
    times = {way: [statistics.median(per[way, q][t] for q in range(sessions)) for t in range(repeats)]
             for way in ways}
    return {"springs": m, "bitwise_same": same, "sessions": sessions, "repeats": repeats,
            "ns_per_spring_step": {way: statistics.median(t) for way, t in times.items()},
            f"{ways[1]}_over_{ways[0]}": _ratio(times[ways[1]], times[ways[0]]),
            "load_average_before": load_before, "load_average_after": os.getloadavg()}


def main(description: str, compare: Callable[..., dict], ways: tuple[str, str], out: Path) -> None:
    """Run ``compare(n, dtype, threads, repeats, sessions)`` for each size, 1 and 2 threads, float32
    and float64; print a line each and write the rows with the machine to ``out``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--repeats", type=int, default=11)
    parser.add_argument("--sessions", type=int, default=4)
    parser.add_argument("--sizes", type=int, nargs="+", default=[300])
    args = parser.parse_args()
    rows = []
    for n in args.sizes:
        for threads in (1, 2):
            for dtype in ("float32", "float64"):
                row = {"n": n, "dtype": dtype, "threads": threads,
                       **compare(n, dtype, threads, args.repeats, args.sessions)}
                rows.append(row)
                ns, r = row["ns_per_spring_step"], row[f"{ways[1]}_over_{ways[0]}"]
                load = row["load_average_before"][0], row["load_average_after"][0]
                print(f"{n}² {dtype} {threads} thread(s): bitwise same {row['bitwise_same']}; ns/spring-step "
                      f"{ways[0]} {ns[ways[0]]:.3f} {ways[1]} {ns[ways[1]]:.3f}; {ways[1]}/{ways[0]} "
                      f"{r['median']:.3f} ({r['min']:.3f}-{r['max']:.3f}); load {load[0]:.2f}-{load[1]:.2f}",
                      flush=True)
    out.write_text(json.dumps({"machine": machine(), "rows": rows}, indent=1) + "\n")
