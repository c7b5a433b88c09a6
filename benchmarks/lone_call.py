"""A lone default ``simulate()`` call against the forced compiled one (issue 38, item 0's done-means).

Usage::

    .venv/bin/python benchmarks/lone_call.py [--repeats 5] [--only NAME]

Goal: every lone default call of >= 0.2 s within 1.5x of the same call with
``backend="numba"`` forced, numba's cache warm, (a) in a fresh process (its first call
pays numba's import and the compiled loop's load) and (b) in a process that has run the
call before. Each repeat starts one fresh process per variant (default, numba; interleaved),
times its first call from the call's start (``Simulation(...)`` and ``advance()``, load
included), then two more calls of the same run in that process. The numpy time of the run
(median of 3 in one more process, after one untimed call) says which runs the goal covers.
Load averages (``os.getloadavg``) are recorded with every figure: on a shared machine
absolute times are inflated, the ratios of interleaved runs much less.

Runs (the ones issue 38 measured from outside): rk4 on a 20-mass 3-D chain at the step that
reaches scipy's RK45 error at rtol 1e-6 (dt 1/800, t_end 2), the chain scene with rk4 (1000
steps), the jelly cube's default run, and 13 steps of a 300x300 cloth (symplectic Euler, the
frame loop's cloth). Writes ``benchmarks/lone_call.json`` (``--out``); ``--code`` runs another
checkout's mslab (the "before" of a change). Nothing here is a test.
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

#: name -> (scene expression, method, dt or None, t_end or None)
RUNS = {
    "chain3d rk4 at 1e-6": ("generators.chain(20, dim=3)", "rk4", 2.0 / 1600, 2.0),
    "chain rk4 1000 steps": ("mslab.load_scene('chain')", "rk4", 1e-3, 1.0),
    "jelly_cube default": ("mslab.load_scene('jelly_cube')", "symplectic_euler", None, None),
    "cloth 300x300, 13 steps": ("frame_cloth(300)", "symplectic_euler", 1 / 960, 13 / 960),
}

LONE = """
import os, sys, time
sys.path.insert(0, sys.argv[6])
import mslab
from mslab.scenes import generators
from benchmarks.frame_loop import frame_cloth
scene = eval(sys.argv[1])
dt = None if sys.argv[3] == "None" else float(sys.argv[3])
t_end = scene.settings.t_end if sys.argv[4] == "None" else float(sys.argv[4])
backend = None if sys.argv[5] == "default" else sys.argv[5]
def once():
    start = time.perf_counter()
    sim = mslab.Simulation(scene, sys.argv[2], dt, t_end=t_end, backend=backend)
    sim.advance()
    return time.perf_counter() - start, sim.compiled
first, compiled = once()
later = [once()[0] for _ in range(int(sys.argv[7]))]
print(first, compiled, os.getloadavg()[0], *later)
"""


#: the mslab tree whose code the processes run (``--code``: e.g. the main branch's, for "before")
CODE = [HERE.parent]


def _python(*args: object) -> list[str]:
    env = {**os.environ, "PYTHONPATH": str(CODE[0])}
    env.pop("MSLAB_BACKEND", None)
    out = subprocess.run([sys.executable, "-c", LONE, *map(str, args)], env=env, capture_output=True,
                         text=True, check=True)
    return out.stdout.split()


def _summary(values: list[float]) -> dict:
    return {"median": statistics.median(values), "min": min(values), "max": max(values), "all": values}


def lone_call(name: str, repeats: int) -> dict:
    """One run's default and forced compiled calls: fresh processes and processes that ran it before."""
    expr, method, dt, t_end = RUNS[name]
    fresh: dict[str, list[float]] = {"default": [], "numba": []}
    warm: dict[str, list[float]] = {"default": [], "numba": []}
    loads, chose = [], None
    for _ in range(repeats):
        for variant in fresh:
            first, compiled, load, *later = _python(expr, method, dt, t_end, variant, CODE[0], 2)
            fresh[variant].append(float(first))
            warm[variant].append(statistics.median(float(t) for t in later))
            loads.append(float(load))
            chose = compiled if variant == "default" else chose
    numpy_calls = [float(t) for t in _python(expr, method, dt, t_end, "numpy", CODE[0], 3)[3:]]
    pairs = {kind: [a / b for a, b in zip(runs["default"], runs["numba"], strict=True)]
             for kind, runs in (("fresh", fresh), ("ran_before", warm))}
    return {"default_compiled": chose == "True", "numpy_s": statistics.median(numpy_calls),
            "fresh": {v: _summary(t) for v, t in fresh.items()},
            "ran_before": {v: _summary(t) for v, t in warm.items()},
            "ratio_fresh": _summary(pairs["fresh"]), "ratio_ran_before": _summary(pairs["ran_before"]),
            "load_average": _summary(loads)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--only", choices=sorted(RUNS), action="append")
    parser.add_argument("--code", type=Path, default=HERE.parent, help="mslab tree to run")
    parser.add_argument("--out", type=Path, default=HERE / "lone_call.json")
    args = parser.parse_args()
    CODE[0] = args.code.resolve()
    names = args.only or list(RUNS)
    for name in names:  # numba's cache warm for every run
        expr, method, dt, t_end = RUNS[name]
        _python(expr, method, dt, t_end, "numba", CODE[0], 0)
    doc = {"machine": machine(), "load_average_start": os.getloadavg(),
           "runs": {name: lone_call(name, args.repeats) for name in names},
           "load_average_end": os.getloadavg()}
    doc["code"] = str(CODE[0])
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    for name, rec in doc["runs"].items():
        rf, rb, la = rec["ratio_fresh"], rec["ratio_ran_before"], rec["load_average"]
        print(f"{name}: numpy {rec['numpy_s']:.3f} s, auto compiled={rec['default_compiled']}; default/numba "
              f"fresh {rf['median']:.2f} ({rf['min']:.2f}-{rf['max']:.2f}), ran before {rb['median']:.2f} "
              f"({rb['min']:.2f}-{rb['max']:.2f}); load {la['min']:.1f}-{la['max']:.1f}")


if __name__ == "__main__":
    main()
