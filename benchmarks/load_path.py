"""A compiled loop that loads at once (issue 38, item 0): its load, and a lone default ``simulate()``.

Usage::

    .venv/bin/python benchmarks/load_path.py [--repeats 7]

1. **Load**: in a fresh process (numba's cache warm), after ``import mslab`` and a one-step
   numpy ``simulate`` of the scene (what any run imports anyway: scipy for the stability
   check), the seconds of ``mslab.fast.stepper(system, method, "numba")``: numba's import
   and the compiled loop's load, i.e. what choosing the compiled loop adds to a run (the
   cost :data:`mslab.fast.LOAD_SECONDS` stands for). ``before`` is the same process with
   :func:`mslab.jit._load_quickly` switched off (numba's own full target set-up before a
   cache load, as before issue 38).
2. The lone default call against the forced compiled one: ``benchmarks/lone_call.py``.

Interleaved repeats, medians with min-max; the machine and its load (``os.getloadavg``) are
recorded. Writes ``benchmarks/load_path.json``. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.suite import machine  # noqa: E402

#: (scene, method, t_end): runs a student writes, numpy time >= 0.2 s on this machine
RUNS = [("chain", "rk4", 1.0), ("jelly_cube", "symplectic_euler", None), ("hanging_rope", "rk4", None)]

LOAD = """
import sys, time
import mslab
from mslab import fast, jit
if sys.argv[1] == "before":
    jit._load_quickly = lambda fast: None
scene = mslab.load_scene(sys.argv[2])
method = mslab.get_method(sys.argv[3])
mslab.simulate(scene, method, t_end=scene.settings.dt, backend="numpy")
start = time.perf_counter()
fast.stepper(scene.system, method, "numba")
print(time.perf_counter() - start)
"""

def _python(code: str, *args: object) -> list[str]:
    env = {**os.environ, "PYTHONPATH": str(HERE.parent)}
    env.pop("MSLAB_BACKEND", None)
    out = subprocess.run([sys.executable, "-c", code, *map(str, args)], env=env, capture_output=True,
                         text=True, check=True)
    return out.stdout.split()


def _summary(values: list[float]) -> dict:
    return {"median": statistics.median(values), "min": min(values), "max": max(values), "all": values}


def load_times(repeats: int) -> dict:
    """Seconds of ``fast.stepper(..., "numba")`` in fresh processes, before and after (interleaved)."""
    out = {}
    for scene, method, _ in RUNS:
        times: dict[str, list[float]] = {"before": [], "after": []}
        for _ in range(repeats):
            for variant in times:
                times[variant].append(float(_python(LOAD, variant, scene, method)[0]))
        out[f"{scene} {method}"] = {v: _summary(t) for v, t in times.items()}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    _python(LOAD, "after", "chain", "rk4")  # numba's cache warm
    doc = {"machine": machine(), "load_average_start": os.getloadavg(),
           "load": load_times(args.repeats),
           "load_average_end": os.getloadavg()}
    (HERE / "load_path.json").write_text(json.dumps(doc, indent=1) + "\n")
    for name, rec in doc["load"].items():
        b, a = rec["before"], rec["after"]
        print(f"load {name}: before {b['median']:.3f} s ({b['min']:.3f}-{b['max']:.3f}), "
              f"after {a['median']:.3f} s ({a['min']:.3f}-{a['max']:.3f})")
    print(f"load average {doc['load_average_start']} -> {doc['load_average_end']}")


if __name__ == "__main__":
    main()
