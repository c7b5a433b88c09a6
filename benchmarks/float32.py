"""float32 against float64 in the compiled loop, in one process (issue 38, item 2).

Usage::

    .venv/bin/python benchmarks/float32.py [--repeats 15] [--sizes 64 128 300] [--sessions 4]

For the frame loop's cloth (``benchmarks/frame_loop.py``: n x n particles, k = 1000, c = 10,
gravity, symplectic Euler at dt = 1/960), sessions of each precision on one thread, then
interleaved repeats, each timing back to back in CPU time: the float64 floor (one vectorised
square root and one division per spring), the float32 floor (the same in float32), 16 steps
of each float64 session and 16 steps of each float32 session (``Simulation.advance(16)``, a
frame). Reported per spring and step: medians of the repeats, and the medians (min-max) of the
per-repeat ratios float32 / float64 and float32 / float32 floor, with the load average before
and after each size. Also the largest difference of the positions after the timed frames,
relative to the cloth's size. Then the default path: sessions of each precision with default
options (all threads), ``advance(16)`` timed in wall-clock time, interleaved with the others:
``default_ns_per_spring_step`` (issue 38's float32 goal is per spring-step of what a user gets).
``--sessions`` (default 4) sessions of each precision and path: a repeat's time is the median of
its sessions' (a session's time moves by up to 1.5x with where its arrays land; before
2026-11-29 15:00 UTC one session each). Written to ``benchmarks/float32.json``. Nothing here is
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

from benchmarks.frame_loop import DT, SUBSTEPS, frame_cloth  # noqa: E402
from benchmarks.suite import machine  # noqa: E402


def floor_kernel():
    """``out[q] = 1 / sqrt(a[q])`` in the precision of ``a`` (the throughput of the two operations)."""
    from numba import njit

    @njit(cache=False, error_model="numpy")
    def floor(a, out):
        one = a.dtype.type(1.0)
        for q in range(a.shape[0]):
            out[q] = one / np.sqrt(a[q])

    return floor


def _ratio(num: list[float], den: list[float]) -> dict:
    r = [a / b for a, b in zip(num, den, strict=True)]
    return {"median": statistics.median(r), "min": min(r), "max": max(r)}


def interleaved(calls: dict, steps: dict, m: int, repeats: int) -> dict[str, list[float]]:
    """CPU times, ns per spring and step, of ``calls`` (``steps[name]`` steps each), interleaved."""
    number = max(1, int(0.02 * 3e8 / (m * SUBSTEPS)))
    times: dict[str, list[float]] = {k: [] for k in calls}
    for _ in range(repeats):
        for name, call in calls.items():
            t = time.process_time()
            for _ in range(number):
                call()
            times[name].append((time.process_time() - t) / number / steps[name] / m * 1e9)
    return times


def compare(n: int, repeats: int, sessions: int = 1) -> dict:
    """Interleaved CPU times per spring-step of both floors and both precisions on one thread.

    ``sessions`` sessions per precision and path (where a session's arrays land moves its time
    by up to 1.5x): a repeat's time of a precision is the median of its sessions' times.
    """
    import mslab
    from mslab import jit
    from mslab.effects import Springs

    scene = frame_cloth(n)
    m = next(e for e in scene.system.effects if isinstance(e, Springs)).i.size
    precisions = ("float64", "float32")
    sims = {d: [mslab.Simulation(scene, "symplectic_euler", dt=DT, backend="numba", threads=1, dtype=d,
                                 check_stability=False) for _ in range(sessions)] for d in precisions}
    defaults = {d: [mslab.Simulation(scene, "symplectic_euler", dt=DT, backend="numba", dtype=d,
                                     check_stability=False) for _ in range(sessions)] for d in precisions}
    floor = floor_kernel()
    arrays = {d: np.random.default_rng(0).uniform(0.5, 2.0, m).astype(d) for d in precisions}
    outs = {d: np.empty_like(a) for d, a in arrays.items()}
    calls = {"floor64": lambda: floor(arrays["float64"], outs["float64"]),
             "floor32": lambda: floor(arrays["float32"], outs["float32"])}
    steps = {"floor64": 1, "floor32": 1}
    for d in precisions:
        for q, sim in enumerate(sims[d]):
            calls[f"{d} {q}"], steps[f"{d} {q}"] = (lambda sim=sim: sim.advance(SUBSTEPS)), SUBSTEPS
    for call in calls.values():
        call()
    for group in defaults.values():
        for sim in group:
            sim.advance(SUBSTEPS)
    wall: dict[str, list[float]] = {d: [] for d in defaults}
    number = max(1, int(0.02 * 3e8 / (m * SUBSTEPS)))
    times: dict[str, list[float]] = {k: [] for k in ("floor64", "floor32", *precisions)}
    load_before = os.getloadavg()
    for _ in range(repeats):
        with jit.threads(1):
            per = interleaved(calls, steps, m, 1)
        for name in ("floor64", "floor32"):
            times[name] += per[name]
        for d in precisions:
            times[d].append(statistics.median(per[f"{d} {q}"][0] for q in range(sessions)))
        for d, group in defaults.items():
            session_times = []
            for sim in group:
                t = time.perf_counter()
                for _ in range(number):
                    sim.advance(SUBSTEPS)
                session_times.append((time.perf_counter() - t) / number / SUBSTEPS / m * 1e9)
            wall[d].append(statistics.median(session_times))
    x64, x32 = sims["float64"][0].state.x, sims["float32"][0].state.x
    size = float(np.ptp(scene.state0.x, axis=0).max())
    return {"n": n, "springs": m, "steps_each": sims["float32"][0].step, "repeats": repeats,
            "sessions": sessions,
            "ns_per_spring_step": {k: statistics.median(t) for k, t in times.items()},
            "float32_over_float64": _ratio(times["float32"], times["float64"]),
            "float32_over_floor32": _ratio(times["float32"], times["floor32"]),
            "float64_over_floor64": _ratio(times["float64"], times["floor64"]),
            "threads": jit.numba().get_num_threads(),
            "default_ns_per_spring_step": {d: statistics.median(w) for d, w in wall.items()},
            "default_float32_range": [min(wall["float32"]), max(wall["float32"])],
            "max_position_difference_over_size": float(np.abs(x64 - x32).max() / size),
            "load_average_before": load_before, "load_average_after": os.getloadavg()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 300])
    parser.add_argument("--sessions", type=int, default=4)
    args = parser.parse_args()
    rows = []
    for n in args.sizes:
        row = compare(n, args.repeats, args.sessions)
        rows.append(row)
        ns, r = row["ns_per_spring_step"], row["float32_over_float64"]
        wall = row["default_ns_per_spring_step"]
        print(f"{n}x{n} ({row['springs']} springs): ns/spring-step f64 {ns['float64']:.2f} "
              f"f32 {ns['float32']:.2f} "
              f"floor64 {ns['floor64']:.2f} floor32 {ns['floor32']:.2f}; f32/f64 {r['median']:.3f} "
              f"({r['min']:.3f}-{r['max']:.3f}); f32/floor32 {row['float32_over_floor32']['median']:.2f}; "
              f"f64/floor64 {row['float64_over_floor64']['median']:.2f}; "
              f"default ({row['threads']} threads, wall) f64 {wall['float64']:.2f} "
              f"f32 {wall['float32']:.2f}; "
              f"load {row['load_average_before'][0]:.2f}-{row['load_average_after'][0]:.2f}", flush=True)
    doc = {"machine": machine(), "rows": rows}
    (HERE / "float32.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
