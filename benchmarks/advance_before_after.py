"""``Simulation.advance`` before and after a change: ``benchmarks/float32.py`` on both, alternated.

Usage::

    .venv/bin/python benchmarks/advance_before_after.py [--before REV] [--rounds 2] [--repeats 11]

Two trees of mslab cannot share one process, so each round runs ``benchmarks/float32.py``
(the frame loop's cloth, ``Simulation.advance(16)`` per timed call, float64 and float32 with
their floors, one thread, CPU time) in a fresh process on a copy of revision ``--before``
(``git archive``; numba's cache of the copy is warm after the first round) and then on this
tree. Reported per size and precision: the medians of the rounds' medians, ns per spring and
step, and after / before of the rounds with their range, each also against its own process's
floor. Written to ``benchmarks/advance_before_after.json``. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.suite import machine  # noqa: E402


def run_float32(root: Path, sizes: list[int], repeats: int) -> list[dict]:
    """Run ``root``'s ``benchmarks/float32.py`` in a fresh process; return its rows."""
    command = [sys.executable, str(root / "benchmarks" / "float32.py"), "--repeats", str(repeats),
               "--sizes", *map(str, sizes)]
    subprocess.run(command, cwd=root, check=True)
    return json.loads((root / "benchmarks" / "float32.json").read_text())["rows"]


def summary(before: list[list[dict]], after: list[list[dict]]) -> list[dict]:
    """Per size and precision: medians over the rounds, after / before per round."""
    out = []
    for k, row in enumerate(after[0]):
        for d in ("float64", "float32"):
            floor = "floor64" if d == "float64" else "floor32"
            old = [r[k]["ns_per_spring_step"][d] for r in before]
            new = [r[k]["ns_per_spring_step"][d] for r in after]
            ratio = [b / a for a, b in zip(old, new, strict=True)]
            out.append({"n": row["n"], "springs": row["springs"], "dtype": d,
                        "before_ns": statistics.median(old), "after_ns": statistics.median(new),
                        "after_over_before": {"median": statistics.median(ratio), "min": min(ratio),
                                              "max": max(ratio)},
                        "after_over_floor": statistics.median(r[k][f"{d}_over_{floor}"]["median"]
                                                              for r in after),
                        "floor_ns": statistics.median(r[k]["ns_per_spring_step"][floor] for r in after),
                        "load_average": [r[k]["load_average_before"][0] for r in after]})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="main")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=11)
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 300])
    args = parser.parse_args()
    runs: dict[str, list[list[dict]]] = {"before": [], "after": []}
    with tempfile.TemporaryDirectory() as folder:
        copy = Path(folder)
        archive = subprocess.run(["git", "archive", args.before], cwd=HERE.parent, capture_output=True,
                                 check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(copy)], input=archive, check=True)
        for _ in range(args.rounds):
            runs["before"].append(run_float32(copy, args.sizes, args.repeats))
            runs["after"].append(run_float32(HERE.parent, args.sizes, args.repeats))
    rows = summary(runs["before"], runs["after"])
    for r in rows:
        q = r["after_over_before"]
        print(f"{r['n']}² {r['dtype']}: before {r['before_ns']:.2f} after {r['after_ns']:.2f} "
              "ns/spring-step; "
              f"after/before {q['median']:.3f} ({q['min']:.3f}-{q['max']:.3f}); "
              f"after/floor {r['after_over_floor']:.2f}")
    doc = {"machine": machine(), "before": args.before, "rows": rows, "runs": runs}
    (HERE / "advance_before_after.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
