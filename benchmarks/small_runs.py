"""Small runs a student writes: the Python around the compiled loop, before and after, in one process.

Usage::

    .venv/bin/python benchmarks/small_runs.py [--repeats 7]

Two costs that grow with the number of steps of a small scene, each timed with today's code
and with the code it replaced (kept callable for this comparison), interleaved repeat by
repeat, default backend, wall-clock time:

``coupled``
    gauss2 and radau_iia2 (fully implicit, Newton on all stages at once) on an 8-particle
    damped 3D chain, 300 steps: Newton's matrix assembled as dense arrays
    (``coupled._dense_coupling``, today) against scipy.sparse products
    (``coupled._sparse_coupling``, before). Same answer bit for bit (checked here).
``saved_every_step``
    leapfrog on the 8-particle soft chain of lesson 06 for 100 s at dt = 0.01, saving every
    step (10,001 samples): the ledger's energies of a chunk of samples at once
    (``Samples.energies``, today) against one state at a time (before). Same ledger bit for bit.

Medians (min-max) of the per-repeat ratios today / before and the times, with the machine and
its load, go to ``benchmarks/small_runs.json``. Nothing here is a test.
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

from benchmarks.suite import machine  # noqa: E402


def per_state_energies(self, k: int) -> None:
    """The ledger's energies one state at a time (the code before the chunks)."""
    system = self.system
    for i in range(self._filled, k):
        self._kinetic[i] = system.kinetic_energy(self.v[i])
        self._potential[i] = system.potential_energy(self.x[i])
        if system.driving:
            self._external[i] = system.external_work(self.x[i], self.x[0])
    self._filled = max(self._filled, k)


def sparse_coupling(system, A, X, V, dt):
    from mslab.integrators.newton import coupled

    return coupled._sparse_coupling(system, A, X, V, dt).toarray()


def timed(call) -> tuple[float, object]:
    start = time.perf_counter()
    result = call()
    return time.perf_counter() - start, result


def compare(run, patch_target, name, old, repeats: int) -> dict:
    """Interleaved wall times of ``run()`` with today's code and with ``old`` patched in."""
    new_fn = getattr(patch_target, name)
    run()  # warm-up (compiled loop loaded)
    times = {"today": [], "before": []}
    results = {}
    for _ in range(repeats):
        for label, fn in (("today", new_fn), ("before", old)):
            setattr(patch_target, name, fn)
            try:
                t, results[label] = timed(run)
            finally:
                setattr(patch_target, name, new_fn)
            times[label].append(t)
    a, b = results["today"], results["before"]
    same = (np.array_equal(a.x, b.x) and np.array_equal(a.v, b.v)
            and all(np.array_equal(getattr(a.energy, part), getattr(b.energy, part))
                    for part in ("kinetic", "potential", "dissipated", "external")))
    ratios = [x / y for x, y in zip(times["today"], times["before"], strict=True)]
    spread = {"median": statistics.median(ratios), "min": min(ratios), "max": max(ratios)}
    return {"seconds_today": statistics.median(times["today"]),
            "seconds_before": statistics.median(times["before"]), "today_over_before": spread,
            "bitwise_same": bool(same), "steps": int(a.stats.steps)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    import mslab
    from mslab import ledger
    from mslab.integrators.newton import coupled
    from mslab.scenes.generators import chain

    load_before = os.getloadavg()
    rows = {}
    damped = chain(8, dim=3, stiffness=200.0, damping=0.4, gamma=0.1)
    for method in ("gauss2", "radau_iia2"):
        rows[f"coupled_{method}"] = compare(
            lambda m=method: mslab.simulate(damped, m, dt=2e-3, t_end=0.6, save_every=7),
            coupled, "_dense_coupling", sparse_coupling, args.repeats)
    soft = chain(n=8, dim=2, stiffness=50.0)
    rows["saved_every_step_leapfrog"] = compare(
        lambda: mslab.simulate(soft, "leapfrog", dt=0.01, t_end=100.0, save_every=1),
        ledger.Samples, "energies", per_state_energies, args.repeats)
    out = {"machine": machine(), "load_average_before": load_before, "load_average_after": os.getloadavg(),
           "repeats": args.repeats, "rows": rows}
    (HERE / "small_runs.json").write_text(json.dumps(out, indent=1) + "\n")
    for name, row in rows.items():
        r = row["today_over_before"]
        print(f"{name:28s} today {row['seconds_today']:.3f} s  before {row['seconds_before']:.3f} s  "
              f"today/before {r['median']:.2f} ({r['min']:.2f}-{r['max']:.2f})  "
              f"same bits: {row['bitwise_same']}")


if __name__ == "__main__":
    main()
