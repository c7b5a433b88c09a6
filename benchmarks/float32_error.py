"""float32 against float64 on the course scenes: the table of docs/precision.md ("float32").

Usage::

    .venv/bin/python benchmarks/float32_error.py

Each row runs one scene with one method over the scene's whole ``t_end`` (its own ``dt`` unless
given), once in float64 and once in float32 (compiled loop, one thread, no stability check),
and reports: the position gap at ``t_end`` (largest over particles and coordinates) relative
to ``X``, the largest coordinate of the float64 run; the same gap over ``N eps32 X`` (the error
model's bound for a stable one-step method, ``N`` steps); the largest gap of the energy ledger
over the saved samples, relative to the scene's energy scale; and each precision's largest
deviation of its ledger from the start, relative to the scale. Written to
``benchmarks/float32_error.json``, and printed as the markdown table. Nothing here is a test
(``tests/test_float32.py`` holds the model's bound on six of these runs).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.suite import machine  # noqa: E402

#: (scene, method, dt or None for the scene's), the rows of docs/precision.md
ROWS = [("chain", "symplectic_euler", None), ("chain", "leapfrog", None), ("chain", "rk4", None),
        ("chain", "verlet", None), ("pendulum", "rk4", None), ("hanging_rope", "rk4", None),
        ("topology_pair", "rk4", None), ("mass_ratio", "rk4", None), ("cloth", "symplectic_euler", 1e-3),
        ("jelly_cube", "symplectic_euler", None), ("cube_no_shear", "symplectic_euler", None),
        ("cloth_on_sphere", "symplectic_euler", None)]


def row(name: str, method: str, dt: float | None) -> dict:
    """The float32 run against the float64 run of one scene and method."""
    import mslab
    from mslab.ledger import initial_energy_scale

    scene = mslab.load_scene(name)
    dt = dt or scene.settings.dt
    steps = int(round(scene.settings.t_end / dt))
    runs = {}
    for dtype in ("float64", "float32"):
        sim = mslab.Simulation(scene, method, dt, backend="numba", threads=1, dtype=dtype,
                               check_stability=False, save_every=scene.settings.save_every)
        sim.advance(steps)
        runs[dtype] = sim
    eps32 = float(np.finfo(np.float32).eps)
    x64, x32 = runs["float64"].state.x, runs["float32"].state.x
    size = float(np.abs(runs["float64"].trajectory.x).max())
    gap = float(np.abs(x32 - x64).max()) / size
    scale = initial_energy_scale(scene)
    e64, e32 = (runs[d].trajectory.energy.total for d in ("float64", "float32"))
    return {"scene": name, "method": method, "dt": dt, "steps": steps, "position_gap_over_X": gap,
            "gap_over_N_eps32_X": gap / (steps * eps32),
            "ledger_gap_over_scale": float(np.abs(e32 - e64).max()) / scale,
            "ledger_deviation_over_scale": {"float64": float(np.abs(e64 - e64[0]).max()) / scale,
                                            "float32": float(np.abs(e32 - e32[0]).max()) / scale}}


def main() -> None:
    import warnings

    import mslab

    warnings.simplefilter("ignore", mslab.StabilityWarning)
    rows = [row(*r) for r in ROWS]
    print("| scene, method | steps | position gap / X | gap / (N eps32 X) | ledger gap / scale "
          "| ledger deviation, float64 / float32 |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        dev = r["ledger_deviation_over_scale"]
        print(f"| {r['scene']}, {r['method']} (dt {r['dt']:g}) | {r['steps']} "
              f"| {r['position_gap_over_X']:.2g} "
              f"| {r['gap_over_N_eps32_X']:.2g} | {r['ledger_gap_over_scale']:.2g} "
              f"| {dev['float64']:.2g} / {dev['float32']:.2g} |")
    doc = {"machine": machine(), "rows": rows}
    (HERE / "float32_error.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
