"""Variants of the spring kernel against the copy bandwidth of the same run (issue 14).

Usage (from a checkout)::

    python benchmarks/spring_variants.py               # 300x300 cloth, writes spring_variants.json
    python benchmarks/spring_variants.py --repeats 7 --only before,now

Every variant computes the spring forces of the 300 x 300 cloth of ``benchmarks/warp_cloth.py``
(checked against the numpy reference to 1e-12, except the probes) and is timed alone,
single-threaded, in CPU time. One repeat times a STREAM-like copy (as ``warp_cloth.py`` does)
and then every variant, in an order rotated from repeat to repeat, back to back; a variant's
share of the copy bandwidth (128 bytes per spring, as issue 14 counts them) and its time over
the first variant's are taken per repeat and reported as median with min and max. The kernels
are in ``benchmarks/spring_variant_kernels.py``. A measurement, not a library path.
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
from numba import njit

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks import spring_variant_kernels as kv  # noqa: E402
from benchmarks.suite import machine  # noqa: E402
from benchmarks.warp_cloth import BYTES_PER_SPRING, _copy_kernel, build_cloth  # noqa: E402
from mslab.effects.spring_kernels import spring_kernel  # noqa: E402

NUMPY = {"error_model": "numpy"}

#: name, kernel, numba options, order of the springs, index dtype, argument form
VARIANTS = (
    ("before: int32 indices (mslab until now)", kv.before, {}, "table", np.int32, "full"),
    ("before, int64 indices", kv.before, {}, "table", np.int64, "full"),
    ("before, uint32 indices", kv.before, {}, "table", np.uint32, "full"),
    ("before, error_model=numpy", kv.before, NUMPY, "table", np.int32, "full"),
    ("before, fastmath=True", kv.before, {"fastmath": True}, "table", np.int32, "full"),
    ("before, greedy order (no neighbouring springs share a particle)", kv.before, {}, "greedy", np.int32,
     "full"),
    ("before, sorted by first particle (neighbours share it)", kv.before, {}, "first", np.int32, "full"),
    ("before, random order", kv.before, {}, "random", np.int32, "full"),
    ("packed (m, 2) indices and (m, 2) stiffness, rest length; int32", kv.packed, NUMPY, "table", np.int32,
     "packed"),
    ("scale form, int32 indices", spring_kernel, {}, "table", np.int32, "full"),
    ("scale form, uint32 indices (mslab now)", spring_kernel, {}, "table", np.uint32, "full"),
    ("scale form, uint32, greedy order", spring_kernel, {}, "greedy", np.uint32, "full"),
    ("scale form, uint32, sorted by lower end (locality)", spring_kernel, {}, "lower", np.uint32, "full"),
    ("scale form, uint32, fastmath contract (FMA)", spring_kernel, {"fastmath": {"contract"}}, "table",
     np.uint32, "full"),
    ("scale form, uint32, square root and division side by side", kv.scale_parallel, NUMPY, "table",
     np.uint32, "hooke"),
    ("scale form, uint32, side by side, guarded for l2 < 1e-300", kv.scale_parallel_guarded, {}, "table",
     np.uint32, "hooke"),
    ("scale form, uint32, two springs per iteration", kv.scale_pair, NUMPY, "table", np.uint32, "hooke"),
    ("scale form, uint32, software-pipelined", kv.scale_pipelined, NUMPY, "table", np.uint32, "hooke"),
    ("scale form, uint32, float32 seed + 2 Newton steps for 1/l", kv.scale_newton, NUMPY, "table", np.uint32,
     "hooke"),
    ("blocks of 32: gather, SIMD sqrt/div (fastmath nsz), scatter; uint32", kv.blocked,
     {"error_model": "numpy", "fastmath": {"nsz"}}, "table", np.uint32, "blocked"),
    ("probe: scale form without its division", kv.probe_no_division, NUMPY, "table", np.uint32, "hooke"),
    ("probe: scale form without its square root", kv.probe_no_sqrt, NUMPY, "table", np.uint32, "hooke"),
    ("probe: memory accesses only, int32", kv.memory_only, NUMPY, "table", np.int32, "hooke"),
    ("probe: memory accesses only, uint32", kv.memory_only, NUMPY, "table", np.uint32, "hooke"),
)


def orders(i: np.ndarray, j: np.ndarray) -> dict:
    """The spring orders compared: the table's, greedy, sorted by first or lower end, random."""
    return {"table": np.arange(i.size), "greedy": kv.greedy_order(i, j),
            "first": np.lexsort((j, i)), "lower": np.lexsort((np.maximum(i, j), np.minimum(i, j))),
            "random": np.random.default_rng(1).permutation(i.size)}


def calls(x, v, springs, only: list[str] | None) -> dict:
    """``name -> (call(f), permutation)`` for the chosen variants, compiled."""
    perms = orders(springs.i, springs.j)
    out = {}
    for name, fn, options, order, dtype, form in VARIANTS:
        if only and not any(o in name for o in only):
            continue
        kern = njit(cache=False, **options)(fn)
        p = perms[order]
        i, j = springs.i[p].astype(dtype), springs.j[p].astype(dtype)
        k, r, c = springs.stiffness[p], springs.rest_length[p], springs.damping[p]
        if form == "full":
            args = (x, v, None, i, j, k, r, c, 0)
        elif form == "packed":
            pair = np.ascontiguousarray(np.stack([i, j], 1))
            args = (x, None, pair, np.ascontiguousarray(np.stack([k, r], 1)))
        elif form == "blocked":
            args = (x, None, i, j, k, r, 32)
        else:
            args = (x, None, i, j, k, r)
        slot = 2 if form == "full" else 1  # where f goes

        def call(f, kern=kern, args=args, slot=slot):
            return kern(*args[:slot], f, *args[slot + 1:])

        out[name] = (call, p)
    return out


def run(n: int, repeats: int, only: list[str] | None, number: int = 5) -> dict:
    """Check every variant, then time them interleaved with the copy; return the figures."""
    _, x0, _, springs, _ = build_cloth(n)
    x = np.ascontiguousarray(x0 + 1e-4 * np.random.default_rng(3).normal(size=x0.shape))
    v = np.zeros_like(x)
    ref = springs.force(x, v)
    table = calls(x, v, springs, only)
    m = springs.i.size
    checks, shared = {}, {}
    for name, (call, perm) in table.items():
        f = np.zeros_like(x)
        call(f)
        shared[name] = kv.shared_neighbours(springs.i[perm], springs.j[perm])
        if not name.startswith("probe"):
            checks[name] = float(np.max(np.abs(f - ref)) / np.max(np.abs(ref)))
            if checks[name] > 1e-12:
                raise AssertionError(f"{name}: differs from the numpy forces by {checks[name]:.3g}")
    copy = _copy_kernel()
    a = np.random.default_rng(0).random(2**24)
    b = np.empty_like(a)
    copy(a, b)
    f = np.zeros_like(x)
    names = list(table)
    t_copy, times = [], {name: [] for name in names}
    for rep in range(repeats):
        t = time.process_time()
        copy(a, b)
        t_copy.append(time.process_time() - t)
        for name in names[rep % len(names):] + names[:rep % len(names)]:
            call = table[name][0]
            t = time.process_time()
            for _ in range(number):
                call(f)
            times[name].append((time.process_time() - t) / number)
    rows = {}
    for name in names:
        shares = [(BYTES_PER_SPRING * m / ts) / (16 * a.size / tc)
                  for tc, ts in zip(t_copy, times[name], strict=True)]
        ratio = [ts / tb for ts, tb in zip(times[name], times[names[0]], strict=True)]
        rows[name] = {"ns_per_spring": 1e9 * statistics.median(times[name]) / m,
                      "share_median": statistics.median(shares), "share_min": min(shares),
                      "share_max": max(shares), "time_over_first_median": statistics.median(ratio),
                      "time_over_first_min": min(ratio), "time_over_first_max": max(ratio),
                      "neighbours_sharing_a_particle": shared[name], "max_rel_difference": checks.get(name)}
    return {"machine": machine(), "n": n, "n_springs": m, "repeats": repeats, "calls_per_repeat": number,
            "copy_bytes_per_s": 16 * a.size / statistics.median(t_copy), "variants": rows,
            "load_average": list(os.getloadavg())}


def table_md(doc: dict) -> str:
    """The variants as a Markdown table."""
    rows = ["| variant | ns/spring | share of copy bandwidth: median (min-max) | time / first row: median "
            "(min-max) | neighbouring springs sharing a particle |", "|---|---|---|---|---|"]
    for name, r in doc["variants"].items():
        rows.append(f"| {name} | {r['ns_per_spring']:.2f} | {100 * r['share_median']:.0f} % "
                    f"({100 * r['share_min']:.0f}-{100 * r['share_max']:.0f} %) | "
                    f"{r['time_over_first_median']:.2f} ({r['time_over_first_min']:.2f}-"
                    f"{r['time_over_first_max']:.2f}) | {r['neighbours_sharing_a_particle']} |")
    return "\n".join(rows)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--only", default="", help="comma-separated substrings of variant names")
    parser.add_argument("--out", default=str(HERE / "spring_variants.json"))
    args = parser.parse_args()
    doc = run(args.n, args.repeats, [s for s in args.only.split(",") if s] or None)
    Path(args.out).write_text(json.dumps(doc, indent=2) + "\n")
    print(table_md(doc))
    load = ", ".join(f"{x:.2f}" for x in doc["load_average"])
    print(f"copy {doc['copy_bytes_per_s'] / 1e9:.1f} GB/s; load average {load}; {doc['machine']['cpu']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
