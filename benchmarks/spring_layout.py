"""The spring kernel before and after a change, in one process (issue 38, item 1).

Usage::

    .venv/bin/python benchmarks/spring_layout.py [--before REV] [--repeats 21]

``--before`` names a git revision (default ``main``) whose ``mslab/effects/spring_kernels.py``
is loaded beside this tree's (from a temporary folder, compiled by :func:`mslab.jit.compiled`)
and called with the same parameters (this tree's ``Springs.kernel_params()``: the old kernel
reads a run's flags as "a run"). For the frame loop's cloth (``benchmarks/frame_loop.py``:
k = 1000, damped c = 10, and undamped) at 64², 128², 300²: first the two kernels' forces and
powers from the same start, compared bitwise; then interleaved repeats, each timing the floor
(one vectorised square root and division per spring, ``benchmarks/warp_cloth.py``), the old
kernel and the new one back to back in CPU time on one thread (300²: also both cores, wall
time). Medians of the per-repeat ratios with their range and the load average of each size
are written to ``benchmarks/spring_layout.json`` (or ``--out``). Nothing here is a test.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.frame_loop import frame_cloth  # noqa: E402
from benchmarks.suite import machine  # noqa: E402
from benchmarks.warp_cloth import _floor_kernel  # noqa: E402


def old_kernel(rev: str, folder: Path):
    """Return ``spring_kernel`` of revision ``rev``, compiled (numba caches it in ``folder``)."""
    from mslab import jit

    source = subprocess.run(["git", "show", f"{rev}:mslab/effects/spring_kernels.py"], cwd=HERE.parent,
                            capture_output=True, text=True, check=True).stdout
    path = folder / "before_spring_kernels.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("mslab._before_spring_kernels", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return jit.compiled(module.spring_kernel, "the spring kernel before")


def _springs(n: int, damping: float):
    """The cloth's springs effect (damped or not)."""
    from mslab.effects import Springs

    scene = frame_cloth(n) if damping else _undamped(n)
    return next(e for e in scene.system.effects if isinstance(e, Springs)), scene


def _cloth_params(n: int, damping: float):
    """The cloth's spring kernel parameters, a perturbed state and its constant forces."""
    springs, scene = _springs(n, damping)
    rng = np.random.default_rng(n)
    x = scene.state0.x + rng.normal(scale=1e-3, size=scene.state0.x.shape)
    v = rng.normal(scale=0.1, size=x.shape)
    return springs.kernel_params(), x, v, rng.normal(size=x.shape)


def _undamped(n: int):
    from mslab.scenes.generators import cloth

    return cloth(n, n, size=0.02 * (n - 1), mass=0.25 * n * n, structural=1000.0, shear=1000.0, bend=1000.0,
                 gravity=9.81)


def compare(old, new, n: int, damping: float, repeats: int, threads: int) -> dict:
    """Bitwise check, then interleaved CPU (1 thread) or wall (more) times of floor, old and new."""
    from mslab import jit

    params, x, v, f0 = _cloth_params(n, damping)
    m = params[0].size - params[10].size  # springs (not gap springs)
    if "gaps" not in old.py_func.__code__.co_varnames:  # a kernel from before gap springs: its own table
        from benchmarks.advance_ab import table_without_gaps

        old_params = table_without_gaps(_springs(n, damping)[0])
        old_kernel, old = old, lambda x, v, f, *_: old_kernel(x, v, f, *old_params)
    f_old, f_new = f0.copy(), f0.copy()
    with jit.threads(threads):
        p_old, p_new = old(x, v, f_old, *params), new(x, v, f_new, *params)
    bitwise = bool(np.array_equal(f_old, f_new) and p_old == p_new)
    floor, a = _floor_kernel(), np.random.default_rng(0).uniform(0.5, 2.0, m)
    out = np.empty_like(a)
    floor(a, out)
    clock = time.process_time if threads == 1 else time.perf_counter
    f = f0.copy()
    number = max(1, int(0.03 * 3e8 / m))
    times: dict[str, list[float]] = {"floor": [], "old": [], "new": []}
    with jit.threads(threads):
        for _ in range(repeats):
            for name, call in (("floor", lambda: floor(a, out)), ("old", lambda: old(x, v, f, *params)),
                               ("new", lambda: new(x, v, f, *params))):
                t = clock()
                for _ in range(number):
                    call()
                times[name].append((clock() - t) / number / m * 1e9)
    ratio = [b / a for a, b in zip(times["old"], times["new"], strict=True)]
    to_floor = [b / a for a, b in zip(times["floor"], times["new"], strict=True)]
    return {"n": n, "springs": m, "damped": bool(damping), "threads": threads, "bitwise": bitwise,
            "ns_per_spring": {k: statistics.median(t) for k, t in times.items()},
            "new_over_old": {"median": statistics.median(ratio), "min": min(ratio), "max": max(ratio)},
            "new_over_floor": statistics.median(to_floor), "load_average": os.getloadavg()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="main")
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 300])
    parser.add_argument("--out", default="spring_layout.json", help="file name in benchmarks/")
    args = parser.parse_args()
    from mslab import jit
    from mslab.effects.spring_kernels import spring_kernel

    new = jit.compiled(spring_kernel)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        old = old_kernel(args.before, Path(folder))
        for n in args.sizes:
            for damping in (0.0, 10.0):
                for threads in (1, 2) if n >= 300 else (1,):
                    row = compare(old, new, n, damping, args.repeats, threads)
                    rows.append(row)
                    r, ns = row["new_over_old"], row["ns_per_spring"]
                    print(f"{n}x{n} damped={row['damped']} threads={threads}: bitwise {row['bitwise']}, "
                          f"ns/spring old {ns['old']:.2f} new {ns['new']:.2f} "
                          f"floor {ns['floor']:.2f}; new/old {r['median']:.3f} "
                          f"({r['min']:.3f}-{r['max']:.3f}); load {row['load_average'][0]:.1f}", flush=True)
    doc = {"machine": machine(), "before": args.before, "rows": rows}
    (HERE / args.out).write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
