"""Compute lesson 03's long runs on the firm chain once and store them: ``lessons/03_long_runs.json``.

Usage (from the repository root)::

    .venv/bin/python tools/lesson03_long_runs.py            # writes lessons/03_long_runs.json
    .venv/bin/python tools/lesson03_long_runs.py --check    # recomputes, exit 1 if the file differs

Lesson 03 shows that a symplectic method's energy band on a firm chain (10 points, k = 1e5 N/m)
stays a band over 200 s: symplectic Euler and leapfrog at two steps and RK4 at the larger one,
3.5 million steps. Those runs take about 10 s of CPU, which together with the rest of the lesson
came too close to the limit a lesson may cost (``tools/lesson_times.py``), so this script runs
them with :func:`mslab.precision.energy_drift`, with the lesson's arguments, and stores each
run's summary and saved samples as :mod:`lesson06_long_runs` does; the lesson rebuilds the
:class:`~mslab.precision.Drift` objects from the file. The runs are deterministic (fixed steps,
the compiled backend), so rerunning the script reproduces the file.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lesson06_long_runs import ROOT, stored_run, write_or_check  # noqa: E402

from mslab.precision import energy_drift  # noqa: E402
from mslab.scenes.generators import chain  # noqa: E402

OUT = ROOT / "lessons" / "03_long_runs.json"
#: The lesson's firm chain, its steps and horizon; RK4 runs at the larger step only.
STIFFNESS, T_END = 1e5, 200.0
RUNS = {4e-4: ("symplectic_euler", "leapfrog", "rk4"), 2e-4: ("symplectic_euler", "leapfrog")}


def compute() -> dict:
    """Run the lesson's long runs; return the data to store."""
    firm = chain(n=10, dim=2, stiffness=STIFFNESS)
    runs = {repr(dt): {name: stored_run(d) for name, d in
                       energy_drift(firm, list(names), dt=dt, t_end=T_END, backend="numba").items()}
            for dt, names in RUNS.items()}
    setup = {"scene": f"chain(n=10, dim=2, stiffness={STIFFNESS:g})", "t_end": T_END,
             "runs": {repr(dt): list(names) for dt, names in RUNS.items()},
             "made_by": "tools/lesson03_long_runs.py"}
    return {"setup": setup, "runs": runs}


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` compare) ``lessons/03_long_runs.json``."""
    return write_or_check(OUT, compute, argv)


if __name__ == "__main__":
    sys.exit(main())
