"""What one call of a student's function costs the grader, with and without a cgroup.

Usage: ``python benchmarks/grading_calls.py [--calls 2000] [--repeats 5]``; writes
``benchmarks/grading_calls.json``. Nothing here is a test.

A hidden test of exercise 02 calls a student's step function some 850 times through the
sandbox (:class:`mslab.grading.remote.Student`: one JSON line each way, decoded strictly).
Here a sandbox in the machine's isolation (bubblewrap or the namespace jail) answers
``calls`` calls of a step on (5, 2) arrays, timed in the runner (wall clock and the runner's
CPU time): once in a box with a cgroup (as root graders have) and once without (the box
meters the sandbox's CPU time from ``/proc``, as an unprivileged grader does), medians of
``repeats``. The load average before and after is recorded.
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

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.suite import machine  # noqa: E402
from mslab.grading import box, isolation  # noqa: E402
from mslab.grading.remote import Sandbox, Student  # noqa: E402

STEP = "def step(x, v, dt):\n    return x + dt * v, v\n"


def per_call(mode: str, cgroups: dict | None, calls: int, repeats: int) -> dict:
    """Median wall and runner-CPU microseconds per call (and their ranges) over ``repeats``."""
    with tempfile.TemporaryDirectory() as folder:
        module = Path(folder) / "student.py"
        module.write_text(STEP)
        sandbox = Sandbox(module, Path(folder), mode=mode, cgroups=cgroups)
        walls, cpus = [], []
        try:
            x, v = np.zeros((5, 2)), np.ones((5, 2))
            for _ in range(repeats):
                step = Student(sandbox, 60.0).step  # a fresh limit per repeat, as per test
                for _ in range(20):
                    step(x, v, 0.01)
                t, c = time.perf_counter(), time.process_time()
                for _ in range(calls):
                    step(x, v, 0.01)
                walls.append((time.perf_counter() - t) / calls * 1e6)
                cpus.append((time.process_time() - c) / calls * 1e6)
        finally:
            sandbox.close()
    return {"wall_us": statistics.median(walls), "wall_range": [min(walls), max(walls)],
            "runner_cpu_us": statistics.median(cpus)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    mode = isolation.detect("auto")
    result = {"machine": machine(), "isolation": mode, "calls": args.calls, "repeats": args.repeats,
              "load_before": os.getloadavg()[0]}
    cgroups, why = box.setup(1, f"mslab-grade-bench-{os.getpid()}")
    try:
        result["cgroup"] = per_call(mode, cgroups, args.calls, args.repeats) if cgroups else {"skipped": why}
    finally:
        box.teardown(cgroups)
    result["no_cgroup"] = per_call(mode, None, args.calls, args.repeats)
    result["load_after"] = os.getloadavg()[0]
    text = json.dumps(result, indent=2)
    print(text)
    (ROOT / "benchmarks" / "grading_calls.json").write_text(text + "\n")


if __name__ == "__main__":
    main()
