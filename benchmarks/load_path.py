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
2. **Lone call**: one ``simulate()`` of a run whose numpy time is >= 0.2 s, backend left to
   its default against ``backend="numba"`` forced, each in a fresh process timed from the
   call's start (load included), and in one process that has run before (interleaved).

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

LONE = """
import sys, time
import mslab
scene = mslab.load_scene(sys.argv[1])
t_end = scene.settings.t_end if sys.argv[3] == "None" else float(sys.argv[3])
backend = None if sys.argv[4] == "default" else sys.argv[4]
def once():
    start = time.perf_counter()
    sim = mslab.Simulation(scene, sys.argv[2], t_end=t_end, backend=backend)
    sim.advance()
    return time.perf_counter() - start, sim.compiled
first = once()
print(first[0], first[1], *(once()[0] for _ in range(int(sys.argv[5]))))
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


def lone_calls(repeats: int) -> dict:
    """A lone default call against the forced compiled one: fresh processes, and one warm process."""
    out = {}
    for scene, method, t_end in RUNS:
        fresh: dict[str, list[float]] = {"default": [], "numba": []}
        warm: dict[str, list[float]] = {"default": [], "numba": []}
        chose = None
        for _ in range(repeats):
            for variant in fresh:
                first, compiled, *later = _python(LONE, scene, method, t_end, variant, 2)
                fresh[variant].append(float(first))
                warm[variant] += [float(t) for t in later]
                chose = compiled if variant == "default" else chose
        numpy_s = statistics.median(float(_python(LONE, scene, method, t_end, "numpy", 0)[0])
                                    for _ in range(3))
        out[f"{scene} {method} t_end={t_end}"] = {
            "default_compiled": chose, "numpy_s": numpy_s,
            "fresh": {v: _summary(t) for v, t in fresh.items()},
            "ran_before": {v: _summary(t) for v, t in warm.items()},
            "ratio_fresh": statistics.median(fresh["default"]) / statistics.median(fresh["numba"]),
            "ratio_ran_before": statistics.median(warm["default"]) / statistics.median(warm["numba"])}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    _python(LOAD, "after", "chain", "rk4")  # numba's cache warm
    for scene, method, t_end in RUNS:
        _python(LONE, scene, method, t_end, "numba", 0)
    doc = {"machine": machine(), "load_average_start": os.getloadavg(),
           "load": load_times(args.repeats), "lone": lone_calls(args.repeats),
           "load_average_end": os.getloadavg()}
    (HERE / "load_path.json").write_text(json.dumps(doc, indent=1) + "\n")
    for name, rec in doc["load"].items():
        b, a = rec["before"], rec["after"]
        print(f"load {name}: before {b['median']:.3f} s ({b['min']:.3f}-{b['max']:.3f}), "
              f"after {a['median']:.3f} s ({a['min']:.3f}-{a['max']:.3f})")
    for name, rec in doc["lone"].items():
        print(f"lone {name}: numpy {rec['numpy_s']:.3f} s, auto compiled={rec['default_compiled']}; "
              f"default/numba fresh {rec['ratio_fresh']:.2f}, ran before {rec['ratio_ran_before']:.2f}")
    print(f"load average {doc['load_average_start']} -> {doc['load_average_end']}")


if __name__ == "__main__":
    main()
