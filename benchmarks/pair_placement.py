"""Where a run's pair buffer lies in the page: 4K aliasing in the pair loop (issue 38, tried and not taken).

Usage::

    .venv/bin/python benchmarks/pair_placement.py [--n 64] [--step 128]

The pair loop of a run (:func:`mslab.effects.spring_kernels.run_pair` over springs ``t``
joining particles ``t`` and ``t + shift``, damped, coordinate-major ``x``, ``v``) stores the
pair forces and powers while it loads ``x``, ``v`` and the rest lengths. A load whose address
matches an older store still in flight in its lowest 12 bits waits for it (4K aliasing). Here
``x`` starts on a page, ``v`` half a page on, the rest lengths at 512 bytes, and the pair
buffer (rows ``(3, m + 7)``, powers 1 KiB after it) is moved through the page in ``--step``
bytes: for each place, CPU time per spring of 100 calls, the best of three. Reported per
precision and ``shift`` (1, n, n + 1, 2n: a cloth's run kinds): the time at the best place
(ns per spring) and the median and largest time over all places relative to it. Written to
``benchmarks/pair_placement.json``. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.suite import machine  # noqa: E402


def pair_loop():
    """A compiled loop: ``reps`` times the damped pair loop of one run (the kernel's ``run_pair``)."""
    from numba import njit

    from mslab.effects.spring_kernels import run_pair
    from mslab.jit import compiled

    pair = compiled(run_pair, error_model="numpy")

    @njit(cache=False, error_model="numpy")
    def loop(x, v, shift, m, rest, out, rates, reps):
        k, c = rest.dtype.type(1000.0), rest.dtype.type(10.0)
        for _ in range(reps):
            for t in range(m):
                q = np.uint64(t)
                pair(x, v, np.uint64(0), np.uint64(shift), q, k, rest[q], c, 1, out, rates)

    return loop


def placed(shape: tuple, dtype: type, offset: int) -> np.ndarray:
    """An empty C-contiguous array whose data start ``offset`` bytes into a page."""
    size = int(np.prod(shape)) * np.dtype(dtype).itemsize
    raw = np.empty(size + 8192 + offset, np.uint8)
    start = (-raw.ctypes.data) % 4096 + offset
    return raw[start:start + size].view(dtype).reshape(shape)


def sweep(loop, n: int, dtype: type, step: int) -> dict:
    rng = np.random.default_rng(1)
    x = placed((3, n * n), dtype, 0)
    x[:] = rng.random((3, n * n))
    v = placed((3, n * n), dtype, 2048)
    v[:] = 0.1 * rng.random((3, n * n))
    result = {}
    for shift in (1, n, n + 1, 2 * n):
        m = n * n - shift
        rest = placed((m,), dtype, 512)
        rest[:] = 0.01
        times = []
        for offset in range(0, 4096, step):
            out = placed((3, m + 7), dtype, offset)
            rates = placed((m + 7,), dtype, (offset + 1024) % 4096)
            loop(x.T, v.T, shift, m, rest, out, rates, 1)
            best = []
            for _ in range(3):
                t0 = time.process_time()
                loop(x.T, v.T, shift, m, rest, out, rates, 100)
                best.append((time.process_time() - t0) / 100 / m * 1e9)
            times.append(min(best))
        low = min(times)
        result[str(shift)] = {"best_ns_per_spring": low, "median_over_best": statistics.median(times) / low,
                              "worst_over_best": max(times) / low, "ns_per_spring": times}
        median = statistics.median(times) / low
        print(f"{np.dtype(dtype).name} shift {shift}: best {low:.2f} ns/spring, median {median:.2f}x,"
              f" worst {max(times) / low:.2f}x", flush=True)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=64)
    parser.add_argument("--step", type=int, default=128)
    args = parser.parse_args()
    loop = pair_loop()
    out = {"machine": machine(), "n": args.n, "step_bytes": args.step,
           "results": {np.dtype(d).name: sweep(loop, args.n, d, args.step) for d in (np.float32, np.float64)}}
    (HERE / "pair_placement.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
