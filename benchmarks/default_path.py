"""What a user gets without options (issue 21): the chain's work-precision sweep, default vs compiled.

Usage::

    .venv/bin/python benchmarks/default_path.py [--repeats 3]

Each variant runs in a fresh process (numba's cache warm, as after a first use), the whole
job timed from the interpreter's start to its end, so the one-time load of the compiled
code is inside the figure: ``mslab precision chain``'s sweep (the course's methods, the
CLI's five steps, timing with 3 repeats, no scipy curves) with ``backend`` left to its
default, and with ``backend="numba"`` forced. Interleaved repeats, median; the ratio is
the figure of issue 21 (goal: default within 1.5x of forced compiled). Writes
``benchmarks/default_path.json``. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.suite import machine  # noqa: E402

SWEEP = """
import sys
import mslab
from mslab import precision
from mslab.commands.precision import course_methods
scene = mslab.load_scene("chain")
t_end = scene.settings.t_end
dts = precision.whole_dts([scene.settings.dt * 2 ** k for k in (4, 3, 2, 1, 0)], t_end)
backend = sys.argv[1] if sys.argv[1] != "default" else None
records = precision.work_precision(scene, course_methods(), dts, t_end, timing=True, repeats=3,
                                   backend=backend)
print(sorted({r["backend"] for r in records}))
"""


def run(variant: str) -> tuple[float, str]:
    """Seconds of one fresh process running the sweep, and the backends it reports."""
    env = {**os.environ, "PYTHONPATH": str(HERE.parent)}
    env.pop("MSLAB_BACKEND", None)
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", SWEEP, variant], env=env, capture_output=True, text=True,
                         check=True)
    return time.perf_counter() - start, out.stdout.strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    run("numba")  # numba's cache warm for both variants
    times: dict[str, list[float]] = {"default": [], "numba": []}
    backends = {}
    for _ in range(args.repeats):
        for variant in times:
            seconds, used = run(variant)
            times[variant].append(seconds)
            backends[variant] = used
    default, compiled = (statistics.median(times[v]) for v in ("default", "numba"))
    doc = {"machine": machine(), "load_average": os.getloadavg(), "sweep": "mslab precision chain, no scipy",
           "seconds": times, "backends": backends, "default_s": default, "numba_s": compiled,
           "ratio_default_over_numba": default / compiled}
    (HERE / "default_path.json").write_text(json.dumps(doc, indent=1) + "\n")
    print(f"sweep, default backend: {default:.2f} s  forced numba: {compiled:.2f} s  "
          f"ratio {default / compiled:.2f}  (backends used: {backends})")


if __name__ == "__main__":
    main()
