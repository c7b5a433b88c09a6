"""What a user gets without options (issue 21): the chain's work-precision sweep, default vs compiled.

Usage::

    .venv/bin/python benchmarks/default_path.py [--repeats 3]

Each variant runs in a fresh process (numba's cache warm, as after a first use), the whole
job timed from the interpreter's start to its end, so the one-time load of the compiled
code is inside the figure: ``mslab precision chain``'s sweep (the course's methods, the
CLI's five steps, timing with 3 repeats, no scipy curves) with ``backend`` left to its
default, and with ``backend="numba"`` forced. Interleaved repeats, median; the ratio is
the figure of issue 21 (goal: default within 1.5x of forced compiled).

Then, in one more fresh process, rk4 against scipy's DOP853 at the same final error (issue
21: rk4 on the default path at an error of 1e-6 within 0.5x DOP853's time): rk4's records
of that default sweep (the backend the job chose; errors and minimum-of-3 times as the
sweep records them) and DOP853 over rtol = atol = 1e-3 ... 1e-10 with mslab's *compiled*
right-hand side (scipy's best case), errors against the sweep's own reference, the minimum
of 3 timed runs; each time at 1e-6 read off its curve (log-log interpolation between
the two runs around it). Writes ``benchmarks/default_path.json``. Nothing here is a test.
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
from mslab.commands.common import course_methods
scene = mslab.load_scene("chain")
t_end = scene.settings.t_end
dts = precision.whole_dts([scene.settings.dt * 2 ** k for k in (4, 3, 2, 1, 0)], t_end)
backend = sys.argv[1] if sys.argv[1] != "default" else None
records = precision.work_precision(scene, course_methods(), dts, t_end, timing=True, repeats=3,
                                   backend=backend)
print(sorted({r["backend"] for r in records}))
"""


MATCHED = """
import json
import time
import numpy as np
from scipy.integrate import solve_ivp
import mslab
from mslab import fast, precision
from mslab.commands.common import course_methods
from mslab.precision.reference import reference_solution
scene = mslab.load_scene("chain")
t_end = scene.settings.t_end
dts = precision.whole_dts([scene.settings.dt * 2 ** k for k in (4, 3, 2, 1, 0)], t_end)
records = precision.work_precision(scene, course_methods(), dts, t_end, timing=True, repeats=3)
rk4 = [(r["error"], r["wall_time"], r["backend"]) for r in records if r["method"] == "rk4"]
ref = reference_solution(scene, t_end)
model = fast.ForceModel(scene.system)
shape, size = scene.state0.x.shape, scene.state0.x.size
def f(t, y):
    a, _ = model.rhs(y[:size].reshape(shape), y[size:].reshape(shape))
    return np.concatenate([y[size:], a.ravel()])
y0 = np.concatenate([scene.state0.x.ravel(), scene.state0.v.ravel()])
dop = []
for k in range(3, 11):
    rtol = 10.0 ** -k
    best = np.inf
    for _ in range(4):
        start = time.perf_counter()
        sol = solve_ivp(f, (0.0, t_end), y0, method="DOP853", rtol=rtol, atol=rtol)
        best = min(best, time.perf_counter() - start)
    y = sol.y[:, -1]
    err = max(float(np.max(np.abs(y[:size].reshape(shape) - ref.x_end))),
              float(np.max(np.abs(y[size:].reshape(shape) - ref.v_end))))
    dop.append((err, best, int(sol.nfev)))
print(json.dumps({"rk4": rk4, "dop853": dop}))
"""


def at_error(curve: list, target: float) -> float:
    """Time at ``target`` error on a (error, time, ...) curve: log-log between the runs around it."""
    import math

    points = sorted((c[0], c[1]) for c in curve)
    for (e_lo, t_lo), (e_hi, t_hi) in zip(points, points[1:], strict=False):
        if e_lo <= target <= e_hi:
            w = (math.log(target) - math.log(e_lo)) / (math.log(e_hi) - math.log(e_lo))
            return math.exp(math.log(t_lo) + w * (math.log(t_hi) - math.log(t_lo)))
    return math.nan


def matched(repeats: int) -> dict:
    """rk4 on the default path and DOP853 (compiled right-hand side) at an error of 1e-6."""
    env = {**os.environ, "PYTHONPATH": str(HERE.parent)}
    env.pop("MSLAB_BACKEND", None)
    ratios, runs = [], []
    for _ in range(repeats):
        out = subprocess.run([sys.executable, "-c", MATCHED], env=env, capture_output=True, text=True,
                             check=True)
        doc = json.loads(out.stdout.strip().splitlines()[-1])
        t_rk4, t_dop = at_error(doc["rk4"], 1e-6), at_error(doc["dop853"], 1e-6)
        ratios.append(t_rk4 / t_dop)
        runs.append({**doc, "rk4_s_at_1e-6": t_rk4, "dop853_s_at_1e-6": t_dop})
    return {"ratio_rk4_over_dop853_at_1e-6": statistics.median(ratios), "ratios": ratios, "runs": runs}


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
           "ratio_default_over_numba": default / compiled, "matched_error": matched(args.repeats)}
    (HERE / "default_path.json").write_text(json.dumps(doc, indent=1) + "\n")
    print(f"sweep, default backend: {default:.2f} s  forced numba: {compiled:.2f} s  "
          f"ratio {default / compiled:.2f}  (backends used: {backends})")
    m = doc["matched_error"]
    print(f"at an error of 1e-6, rk4 on the default path / DOP853 (compiled right-hand side): "
          f"{m['ratio_rk4_over_dop853_at_1e-6']:.2f} (runs {', '.join(f'{r:.2f}' for r in m['ratios'])}; "
          f"rk4 backend {sorted({b for r in m['runs'] for *_, b in r['rk4']})})")


if __name__ == "__main__":
    main()
