"""The energy ledger's periodic check in a compiled session: numpy's spring energy against the compiled sum.

Usage::

    .venv/bin/python benchmarks/ledger_check.py [--repeats 9] [--sizes 64 128 300]

The frame loop's cloth (``benchmarks/frame_loop.py``), default options (all threads), frames
of 16 symplectic-Euler steps through ``Simulation.advance(16)``; 8 frames (128 steps, one
ledger check) timed per repeat. ``before``: a session whose springs compute the check's energy
with numpy (``Springs.energy``, as before issue 38's change); ``after``: the default (the
compiled ``Springs.compiled_energy``). Two scenes, sessions interleaved, wall time, ratio
after / before per repeat: median (min-max); the energies of one check both ways. Writes
``benchmarks/ledger_check.json`` with the machine and the load. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.frame_loop import DT, SUBSTEPS, frame_cloth  # noqa: E402
from benchmarks.suite import machine  # noqa: E402


def compare(n: int, repeats: int) -> dict:
    """Milliseconds per frame with the numpy and the compiled check, interleaved."""
    import mslab
    from mslab.effects import Springs

    sims = {}
    for name in ("before", "after"):
        scene = frame_cloth(n)
        springs = next(e for e in scene.system.effects if isinstance(e, Springs))
        if name == "before":
            springs.compiled_energy = springs.energy  # the numpy sum, as before
        sims[name] = mslab.Simulation(scene, "symplectic_euler", dt=DT)
        sims[name].advance(8 * SUBSTEPS)
    x = sims["after"].state.x
    energies = {"numpy": springs.energy(x), "compiled": Springs.compiled_energy(springs, x)}
    times: dict[str, list[float]] = {k: [] for k in sims}
    load = os.getloadavg()
    for _ in range(repeats):
        for name, sim in sims.items():
            start = time.perf_counter()
            for _ in range(8):
                sim.advance(SUBSTEPS)
            times[name].append((time.perf_counter() - start) / 8 * 1e3)
    ratios = [a / b for a, b in zip(times["after"], times["before"], strict=True)]
    summary = {"median": statistics.median(ratios), "min": min(ratios), "max": max(ratios)}
    return {"n": n, "springs": int(springs.i.size), "repeats": repeats,
            "ms_per_frame": {k: statistics.median(t) for k, t in times.items()}, "after_over_before": summary,
            "check_energy": energies, "load_average_before": load, "load_average_after": os.getloadavg()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 300])
    args = parser.parse_args()
    rows = []
    for n in args.sizes:
        row = compare(n, args.repeats)
        rows.append(row)
        ms, r = row["ms_per_frame"], row["after_over_before"]
        print(f"{n}x{n}: ms/frame numpy check {ms['before']:.2f}, compiled check {ms['after']:.2f}; "
              f"after/before {r['median']:.3f} ({r['min']:.3f}-{r['max']:.3f}); "
              f"load {row['load_average_before'][0]:.2f}-{row['load_average_after'][0]:.2f}", flush=True)
    (HERE / "ledger_check.json").write_text(json.dumps({"machine": machine(), "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
