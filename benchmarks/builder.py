"""Building a cloth the README's way: ``add_particle`` and ``add_spring`` in Python loops (issue 28).

Usage (from a checkout)::

    python benchmarks/builder.py                    # sides 40, 120, 300; writes builder.json
    python benchmarks/builder.py --sides 20,40 --no-save

A 3D cloth of ``side x side`` particles gets its structural, shear and bend springs (the
pairs of :func:`mslab.scenes.generators.grid_springs`) one ``add_spring`` call at a time,
as a student following the quick start writes it; the same scene is then built with one
``add_particles`` and one ``add_springs(pairs)`` call per kind. Both scenes are checked
identical (positions, masses, springs, parameters, kinds). Reported per side: seconds of
each loop and of ``build()``, microseconds per spring, and the ratio of the loop to the
vectorised build. The vectorised build is the median of a few repeats; the loop runs
``--repeats`` times (median) for sides up to 120 and once beyond. A measurement, not a test.
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
from mslab import SceneBuilder  # noqa: E402
from mslab.scenes.generators import grid_springs  # noqa: E402

KINDS = (("structural", 500.0), ("shear", 50.0), ("bend", 5.0))


def cloth_positions(side: int) -> np.ndarray:
    """Particles of a hanging 3D cloth, shape (side * side, 3), in C order of the grid."""
    gx, gz = np.meshgrid(np.linspace(0.0, 1.0, side), np.linspace(-1.0, 0.0, side), indexing="xy")
    return np.stack([gx.ravel(), np.zeros(side * side), gz.ravel()], axis=1)


def build_loop(side: int) -> tuple[object, float, float, float]:
    """The quick-start way: returns ``(scene, s particles, s springs, s build)``."""
    x = cloth_positions(side)
    b = SceneBuilder(dim=3)
    t0 = time.perf_counter()
    for p in x:
        b.add_particle(p, mass=1.0)
    t1 = time.perf_counter()
    for kind, k in KINDS:
        for i, j in grid_springs((side, side), kind).tolist():
            b.add_spring(i, j, stiffness=k, kind=kind)
    t2 = time.perf_counter()
    scene = b.build()
    return scene, t1 - t0, t2 - t1, time.perf_counter() - t2


def build_vectorised(side: int) -> object:
    """One ``add_particles`` and one ``add_springs`` per spring kind, then ``build()``."""
    b = SceneBuilder(dim=3)
    b.add_particles(cloth_positions(side), mass=1.0)
    for kind, k in KINDS:
        b.add_springs(grid_springs((side, side), kind), stiffness=k, kind=kind)
    return b.build()


def same_scene(a, b) -> bool:
    """Equal positions, velocities, masses, springs, spring parameters and kinds (bitwise)."""
    sa, sb = a.springs(), b.springs()
    return (np.array_equal(a.state0.x, b.state0.x) and np.array_equal(a.state0.v, b.state0.v)
            and np.array_equal(a.system.mass, b.system.mass) and np.array_equal(sa.springs, sb.springs)
            and np.array_equal(sa.stiffness, sb.stiffness) and np.array_equal(sa.rest_length, sb.rest_length)
            and np.array_equal(sa.damping, sb.damping) and np.array_equal(a.spring_kind, b.spring_kind))


def measure(side: int, repeats: int) -> dict:
    """Times of both ways for one side (medians), and whether they build the same scene."""
    runs = [build_loop(side) for _ in range(repeats if side <= 120 else 1)]
    scene = runs[0][0]
    particles, springs, build = (statistics.median(r[k] for r in runs) for k in (1, 2, 3))
    vec = []
    for _ in range(5):
        t = time.perf_counter()
        ref = build_vectorised(side)
        vec.append(time.perf_counter() - t)
    n_springs = len(scene.spring_kind)
    total = particles + springs + build
    return {"side": side, "n_particles": side * side, "n_springs": n_springs,
            "add_particle_loop_s": particles, "add_spring_loop_s": springs, "build_s": build,
            "loop_total_s": total, "us_per_spring": 1e6 * springs / n_springs,
            "vectorised_s": statistics.median(vec),
            "ratio_loop_to_vectorised": total / statistics.median(vec),
            "loop_repeats": len(runs), "identical": same_scene(scene, ref)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sides", default="40,120,300")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-save", action="store_true")
    args = parser.parse_args()
    rows = []
    for side in (int(s) for s in args.sides.split(",")):
        row = measure(side, args.repeats)
        rows.append(row)
        print(f"{side:4d} side: {row['n_springs']:7d} springs, particles {row['add_particle_loop_s']:.2f} s, "
              f"springs {row['add_spring_loop_s']:.2f} s ({row['us_per_spring']:.1f} us/spring), build "
              f"{row['build_s']:.2f} s; vectorised {row['vectorised_s']:.3f} s; loop / vectorised "
              f"{row['ratio_loop_to_vectorised']:.0f}; identical: {row['identical']}", flush=True)
    base = rows[0]["us_per_spring"]
    for row in rows:
        row["us_per_spring_over_first"] = row["us_per_spring"] / base
    if not args.no_save:
        out = {"machine": {**machine(), "load_average": os.getloadavg()}, "rows": rows}
        (HERE / "builder.json").write_text(json.dumps(out, indent=1) + "\n")
        write_section(out)


HEADING = "## Building a scene in Python loops (issue 28)"


def section(doc: dict) -> list[str]:
    """RESULTS.md's section of this benchmark, from ``builder.json``."""
    m = doc["machine"]
    load = ", ".join(f"{x:.1f}" for x in m["load_average"])
    lines = [HEADING, "",
             f"Measured {m['date']} by `benchmarks/builder.py`: {m['cpu']}, {m['cores']} cores (shared; load "
             f"average {load} at the end). A 3D cloth built the quick start's way, `add_particle` then "
             "`add_spring` in Python loops (structural, shear, bend pairs), against one `add_particles` "
             "and one `add_springs(pairs)` per kind; both scenes are identical (checked).", "",
             "| side | particles | springs | `add_particle` loop (s) | `add_spring` loop (s) | µs per spring "
             "| `build()` (s) | loop total (s) | vectorised (s) | loop / vectorised | identical |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in doc["rows"]:
        lines.append(f"| {r['side']} | {r['n_particles']:,} | {r['n_springs']:,} "
                     f"| {r['add_particle_loop_s']:.2f} | {r['add_spring_loop_s']:.2f} "
                     f"| {r['us_per_spring']:.1f} | {r['build_s']:.2f} | {r['loop_total_s']:.2f} "
                     f"| {r['vectorised_s']:.3f} | {r['ratio_loop_to_vectorised']:.0f} | {r['identical']} |")
    lines += ["", "Before issue 28 the `add_spring` loop took 192-959 µs per spring, growing with the scene "
              "(a copy of all positions, a scan of the effects folder and a duplicate check per call): "
              "36 s at 80x80, hours at 300x300. `tests/test_builder_cost.py` counts each builder call's "
              "work at two scene sizes.", ""]
    return lines


def write_section(doc: dict) -> None:
    """Put :func:`section` into ``RESULTS.md`` (replacing an earlier one; ``run_bench.py`` keeps it)."""
    path = HERE / "RESULTS.md"
    text = path.read_text()
    if HEADING in text:
        start = text.index(HEADING)
        end = text.find("\n## ", start + len(HEADING))
        text = text[:start] + (text[end + 1:] if end >= 0 else "")
    path.write_text(text.rstrip("\n") + "\n\n" + "\n".join(section(doc)))


if __name__ == "__main__":
    main()
