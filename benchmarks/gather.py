"""Should mslab's spring kernel gather instead of scatter? A measurement, not a library path.

Usage (from a checkout)::

    python benchmarks/gather.py            # 300x300 cloth, writes gather_results.json

The spring kernel of mslab (``mslab/effects/spring_kernels.py``) scatters: one pass over the
springs adds ``+f_q`` to particle ``i`` and ``-f_q`` to ``j``. It cannot run on several
threads without atomics or colouring. The *gather* formulation loops over particles and
sums each particle's incident springs through a CSR adjacency (no write conflicts), so
numba's ``prange`` can split the particles among threads, and the result does not depend on
the thread count (each particle sums its springs in the CSR order). The price: every
spring's force is computed twice (once from each end).

Here a gather kernel (undamped Hooke springs, the cloth's case, the same formula as
mslab's kernel) is timed against mslab's compiled scatter kernel on the 300 x 300 cloth:
one thread and all threads, interleaved repeats, wall time (threads: CPU time would add
them up), the result checked equal to 1e-12 and identical for 1 and N threads. The figures
decide whether the library should get a gather kernel (see ``RESULTS.md``).
"""

import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from numba import get_num_threads, njit, prange, set_num_threads

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))


def adjacency(i: np.ndarray, j: np.ndarray, n: int):
    """CSR of the springs at each particle: ``start[p]:start[p+1]`` index ``spring`` and ``sign``."""
    ends = np.concatenate([i, j])
    springs = np.concatenate([np.arange(i.size), np.arange(i.size)])
    signs = np.concatenate([np.ones(i.size), -np.ones(i.size)])
    order = np.argsort(ends, kind="stable")
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(ends, minlength=n), out=start[1:])
    return start, springs[order].astype(np.int32), signs[order]


def _gather_body(x, f, i, j, stiffness, rest_length, start, spring, sign, p):
    fx = fy = fz = 0.0
    for e in range(start[p], start[p + 1]):
        q = spring[e]
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        inv_l = 1.0 / length if length > 0.0 else 0.0
        k = stiffness[q]
        lu = rest_length[q] * inv_l
        s = sign[e]
        fx += s * (-k * (dx - lu * dx))
        fy += s * (-k * (dy - lu * dy))
        fz += s * (-k * (dz - lu * dz))
    f[p, 0] = fx
    f[p, 1] = fy
    f[p, 2] = fz


_body = njit(inline="always")(_gather_body)


@njit(parallel=True, cache=False)
def gather(x, f, i, j, stiffness, rest_length, start, spring, sign):
    """``f[p] = sum over the springs at p of (+-) the pair force``, particles split among threads."""
    for p in prange(x.shape[0]):
        _body(x, f, i, j, stiffness, rest_length, start, spring, sign, p)


def run(repeats: int = 11) -> dict:
    from benchmarks.suite import machine
    from benchmarks.warp_cloth import build_cloth, mslab_stepper

    scene, x0, v0, springs, _ = build_cloth(300)
    _, _, runner = mslab_stepper(scene, x0, v0, 1e-5)
    mod, params, kernels = runner.model.module, runner.model.params, runner.model.kernels
    n_k = next(q for q, kern in enumerate(kernels) if kern.__name__ == "spring_kernel")
    scatter = getattr(mod, f"_k{n_k}")
    i, j = params[n_k][0], params[n_k][1]
    start, spring, sign = adjacency(springs.i, springs.j, x0.shape[0])
    x = x0.copy()
    fs, fg = np.zeros_like(x), np.zeros_like(x)
    scatter(x, v0, fs, *params[n_k])
    threads = get_num_threads()
    results = {}
    for t in sorted({1, threads}):
        set_num_threads(t)
        gather(x, fg, i, j, springs.stiffness, springs.rest_length, start, spring, sign)
        results[t] = fg.copy()
    scale = float(np.max(np.abs(fs)))
    diff = float(np.max(np.abs(results[1] - fs))) / scale
    same = bool(np.array_equal(results[1], results[threads]))

    def timed(fn) -> float:
        t0 = time.perf_counter()
        for _ in range(5):
            fn()
        return (time.perf_counter() - t0) / 5

    times = {"scatter_1": [], "gather_1": [], f"gather_{threads}": []}
    for _ in range(repeats):
        times["scatter_1"].append(timed(lambda: scatter(x, v0, fs, *params[n_k])))
        for t in sorted({1, threads}):
            set_num_threads(t)
            times[f"gather_{t}"].append(timed(lambda: gather(x, fg, i, j, springs.stiffness,
                                                             springs.rest_length, start, spring, sign)))
    set_num_threads(threads)
    m = springs.i.size
    doc = {"machine": machine(), "threads": threads, "n_springs": int(m), "max_rel_difference": diff,
           "same_for_any_thread_count": same, "load_average": list(os.getloadavg())}
    for key, ts in times.items():
        doc[key] = {"ns_per_spring": 1e9 * statistics.median(ts) / m,
                    "ratio_to_scatter_median": statistics.median(
                        a / b for a, b in zip(ts, times["scatter_1"], strict=True))}
    return doc


def table(doc: dict) -> str:
    """The measurement as Markdown."""
    rows = ["| 300x300 cloth spring forces | ns/spring (wall, median) | time / scatter (median per repeat) |",
            "|---|---|---|"]
    for key in ("scatter_1", "gather_1", f"gather_{doc['threads']}"):
        what = ("mslab's scatter kernel, 1 thread" if key == "scatter_1"
                else f"gather, {key.split('_')[1]} thread(s)")
        t = doc[key]
        rows.append(f"| {what} | {t['ns_per_spring']:.3g} | {t['ratio_to_scatter_median']:.3g} |")
    return "\n".join(rows)


def main() -> int:
    doc = run()
    (HERE / "gather_results.json").write_text(json.dumps(doc, indent=2) + "\n")
    print(table(doc))
    print(f"max rel. difference to scatter {doc['max_rel_difference']:.1e}; identical for 1 and "
          f"{doc['threads']} threads: {doc['same_for_any_thread_count']}; load average {doc['load_average']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
