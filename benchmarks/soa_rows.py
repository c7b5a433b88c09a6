"""The spring kernel on coordinate-major memory against today's, in one process (issue 38, item 1).

Usage::

    .venv/bin/python benchmarks/soa_rows.py [--variant REV] [--repeats 15]

``--variant`` names a git revision whose ``mslab/effects/spring_kernels.py`` has
``spring_rows`` (default: commit a9298a7 of branch h/f32, the experiment, reverted after this
measurement): a run's loop over ``(3, n)`` arrays seen as ``(n, 3)`` (one contiguous row per
coordinate: no shuffles of interleaved x, y, z), its pair forces scattered row by row, and for
undamped runs whose two ends do not overlap the forces added as they are computed. The variant
is loaded beside this tree's kernel (``benchmarks/spring_layout.py``'s loader). For the frame
loop's cloth (``benchmarks/frame_loop.py``: damped, c = 10) and the same cloth undamped at
128² and 300², float64 and float32: the two kernels' forces from the same state, compared
bitwise (today's kernel on ``(n, 3)`` memory, the variant on ``(3, n)``), then interleaved
repeats on one thread, CPU time. Medians (min-max) of the per-repeat ratios variant / today,
with the load average, are written to ``benchmarks/soa_rows.json``. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.spring_layout import _cloth_params, old_kernel  # noqa: E402
from benchmarks.suite import machine  # noqa: E402

VARIANT = "a9298a797bb275a52a9b5c5c54ebcefbcfe0e341"


def compare(today, rows, n: int, damping: float, dtype: str, repeats: int) -> dict:
    """Bitwise check, then interleaved CPU times (one thread) of both kernels per spring."""
    from mslab import jit
    from mslab.fast.model import _param

    params, x, v, f0 = _cloth_params(n, damping)
    params = tuple(_param(p, np.dtype(dtype)) for p in params)
    x, v, f0 = (a.astype(dtype) for a in (x, v, f0))
    major = tuple(np.array(a.T, order="C").T for a in (x, v, f0))  # (3, n) memory seen as (n, 3)
    f_today, f_rows = f0.copy(), major[2].copy(order="K")
    with jit.threads(1):
        p_today, p_rows = today(x, v, f_today, *params), rows(major[0], major[1], f_rows, *params)
    bitwise = bool(np.array_equal(f_today, f_rows) and p_today == p_rows)
    m = params[0].size
    number = max(1, int(0.02 * 3e8 / m))
    times: dict[str, list[float]] = {"today": [], "rows": []}
    f_a, f_b = f0.copy(), f_rows.copy(order="K")
    load = os.getloadavg()
    with jit.threads(1):
        for _ in range(repeats):
            for name, call in (("today", lambda: today(x, v, f_a, *params)),
                               ("rows", lambda: rows(major[0], major[1], f_b, *params))):
                t = time.process_time()
                for _ in range(number):
                    call()
                times[name].append((time.process_time() - t) / number / m * 1e9)
    ratio = [b / a for a, b in zip(times["today"], times["rows"], strict=True)]
    return {"n": n, "springs": m, "damped": bool(damping), "dtype": dtype, "bitwise": bitwise,
            "ns_per_spring": {k: statistics.median(t) for k, t in times.items()},
            "rows_over_today": {"median": statistics.median(ratio), "min": min(ratio), "max": max(ratio)},
            "load_average_before": load, "load_average_after": os.getloadavg()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default=VARIANT)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 300])
    args = parser.parse_args()
    from mslab import jit
    from mslab.effects.spring_kernels import spring_kernel

    today = jit.compiled(spring_kernel)
    out = []
    with tempfile.TemporaryDirectory() as folder:
        rows = old_kernel(args.variant, Path(folder))
        for n in args.sizes:
            for damping in (10.0, 0.0):
                for dtype in ("float64", "float32"):
                    row = compare(today, rows, n, damping, dtype, args.repeats)
                    out.append(row)
                    r, ns = row["rows_over_today"], row["ns_per_spring"]
                    print(f"{n}x{n} damped={row['damped']} {dtype}: bitwise {row['bitwise']}, "
                          f"ns/spring today {ns['today']:.2f} rows {ns['rows']:.2f}; rows/today "
                          f"{r['median']:.3f} ({r['min']:.3f}-{r['max']:.3f}); "
                          f"load {row['load_average_before'][0]:.1f}", flush=True)
    doc = {"machine": machine(), "variant": args.variant, "rows": out}
    (HERE / "soa_rows.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
