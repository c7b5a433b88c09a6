"""Compute lesson 06's long runs once and store their energy errors: ``lessons/06_long_runs.json``.

Usage (from the repository root)::

    .venv/bin/python tools/lesson06_long_runs.py            # writes lessons/06_long_runs.json
    .venv/bin/python tools/lesson06_long_runs.py --check    # recomputes, exit 1 if the file differs

Lesson 06 runs every course method for 30 s on a stiff chain (2.4 million steps), shows that a
symplectic method's energy band stays a band over 300 s (three methods at three steps: 31.5
million steps) and that RK4's loss adds up over the same 300 s. Those runs take about 90 s of
CPU, more than a lesson may cost (``tools/lesson_times.py``, limit 60 s), so this script runs
them with :func:`mslab.precision.energy_drift` and stores each run's summary
(:meth:`mslab.precision.Drift.as_record`, without the wall time) and saved samples (time and
relative energy error); the lesson rebuilds the :class:`~mslab.precision.Drift` objects from the
file (the first code cell of section 1). The runs are deterministic (fixed steps, the compiled
backend), so rerunning the script reproduces the file; ``--check`` compares a fresh run with the stored one.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
import mslab  # noqa: E402
from mslab.precision import Drift, energy_drift  # noqa: E402
from mslab.scenes.generators import chain  # noqa: E402

OUT = ROOT / "lessons" / "06_long_runs.json"
#: The lesson's set-up (sections 1 and 2): the stiff chain, its steps and horizons.
STIFFNESS = 1e5
COURSE_STEP, COURSE_T, COURSE_SAVE = 1e-4, 30.0, 500
STEPS = (2e-4, 1e-4, 5e-5)
SYMPLECTIC = ("symplectic_euler", "verlet", "leapfrog")
LONG_T, LONG_SAVE = 300.0, 1000
DIGITS = 10


def _rounded(values: object) -> list[float]:
    return [float(f"{v:.{DIGITS}g}") for v in np.asarray(values, dtype=float)]


def stored_run(drift: Drift) -> dict:
    """One run: its summary without the wall time, and its saved samples to ``DIGITS`` digits."""
    record = {k: v for k, v in drift.as_record().items() if k != "wall_time"}
    record.update({k: float(f"{record[k]:.{DIGITS}g}") for k in ("max_error", "final_error", "drift_rate",
                                                                   "trend", "early", "late")})
    return {**record, "t": _rounded(drift.t), "error": _rounded(drift.error)}


def compute() -> dict:
    """Run the lesson's long runs; return the data to store."""
    stiff = chain(n=8, dim=2, stiffness=STIFFNESS)
    probe = mslab.simulate(stiff, "leapfrog", dt=COURSE_STEP, t_end=COURSE_T, save_every=20, backend="numba")
    lengths = np.linalg.norm(np.diff(probe.x, axis=1), axis=2) * 7      # / rest length 1/7 m
    explicit = [m for m in mslab.COURSE_METHODS if not m.startswith("implicit")]
    course = energy_drift(stiff, explicit, dt=COURSE_STEP, t_end=COURSE_T, n_save=COURSE_SAVE,
                          backend="numba")
    bands = {}
    for h in STEPS:
        runs = energy_drift(stiff, list(SYMPLECTIC), dt=h, t_end=LONG_T, n_save=LONG_SAVE, backend="numba")
        bands[repr(h)] = {name: stored_run(d) for name, d in runs.items()}
    rk4 = energy_drift(stiff, ["rk4"], dt=COURSE_STEP, t_end=LONG_T, n_save=LONG_SAVE, backend="numba")["rk4"]
    setup = {"scene": f"chain(n=8, dim=2, stiffness={STIFFNESS:g})", "course_step": COURSE_STEP,
             "course_t_end": COURSE_T, "steps": list(STEPS), "methods": list(SYMPLECTIC), "t_end": LONG_T,
             "rk4_step": COURSE_STEP, "made_by": "tools/lesson06_long_runs.py"}
    return {"setup": setup, "strain": _rounded([lengths.min(), lengths.max()]),
            "course": {name: stored_run(d) for name, d in course.items()}, "bands": bands,
            "rk4": stored_run(rk4)}


def write_or_check(out: Path, compute_data: Callable[[], dict], argv: list[str] | None = None) -> int:
    """Write ``compute_data()`` as JSON to ``out``; ``--check``: compare a fresh run, exit 1 if it differs."""
    parser = argparse.ArgumentParser(description="write a lesson's stored long runs; --check compares")
    parser.add_argument("--check", action="store_true", help="recompute and compare with the stored file")
    args = parser.parse_args(argv)
    text = json.dumps(compute_data(), separators=(",", ":")) + "\n"
    if args.check:
        same = out.exists() and json.loads(out.read_text()) == json.loads(text)
        print(f"{out.relative_to(ROOT)}: {'reproduced' if same else 'DIFFERS from a fresh run'}")
        return 0 if same else 1
    out.write_text(text)
    print(f"wrote {out.relative_to(ROOT)} ({len(text) // 1024} KiB)")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` compare) ``lessons/06_long_runs.json``."""
    return write_or_check(OUT, compute, argv)

if __name__ == "__main__":
    sys.exit(main())
