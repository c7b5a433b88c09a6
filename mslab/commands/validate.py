"""``mslab validate FILE...``: check scene files without running them, and say what a run costs.

Prints one line per file: ``FILE: ok (...)`` with the run's cost (steps, saved samples
and their memory, and a time estimate from a few timed steps), or
``mslab: error: FILE: KEY: reason`` on stderr. A scene whose saved data would exceed the
memory budget (``--max-memory``, default half the available memory) is an error here too,
as ``mslab run`` would refuse it; ``--method --dt --t-end --save-every`` override the file's
``[run]`` values as in ``mslab run``, so the fix a refusal suggests can be checked.
``--json`` prints one JSON document on stdout and nothing on stderr; ``--out DIR`` also
writes it to ``DIR/validate.json``. Exit code 0 when every file is valid, 2 otherwise.
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING

from mslab.commands.common import (
    CommandError,
    add_budget_option,
    add_common_options,
    add_settings_options,
    emit_json,
    memory_budget,
    out_path,
    say,
)

if TYPE_CHECKING:
    import argparse

    from mslab.scene import Scene


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab validate`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "validate",
        help="check scene files without running them (and estimate what a run costs)",
        description="Check scene files (or built-in names) and report the first mistake of each as "
                    "one line FILE: KEY: reason; for a valid file, the run's steps, saved samples, "
                    "memory and an estimate of its time from a few timed steps.",
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="scene .toml files or built-in scene names")
    p.add_argument("--no-timing", action="store_true", help="skip the few timed steps of the time estimate")
    add_settings_options(p)
    add_budget_option(p)
    add_common_options(p)
    p.set_defaults(func=run)


def check(name: str, budget: int | None, budget_name: str, timing: bool,
          overrides: dict | None = None) -> dict:
    """Return the validation record of one file: ``ok``, the cost, or ``key``/``reason``/``error``.

    ``overrides``: ``method``, ``dt``, ``t_end``, ``save_every`` replacing the file's ``[run]``
    values, as ``mslab run`` takes them (so a refusal's advice can be checked here).
    """
    from mslab.budget import memory_problem, run_cost, time_per_step
    from mslab.errors import SceneError
    from mslab.progress import Progress
    from mslab.scenes.loader import load_scene

    try:
        scene = load_scene(name, max_bytes=budget, **(overrides or {}))
    except SceneError as err:
        return {"file": name, "ok": False, "key": err.key, "reason": err.reason,
                "error": str(err).splitlines()[0]}
    cost = run_cost(scene)
    problem = memory_problem(cost, budget, budget_name)
    if problem:
        return {"file": name, "ok": False, "key": "run", "reason": problem,
                "error": f"{name}: run: {problem}", "cost": cost.as_dict()}
    record = {"file": name, "ok": True, **scene.summary(), "steps": cost.steps, "cost": cost.as_dict(),
              "seconds_per_step": None, "estimated_seconds": None}
    record.update(_stability(scene))
    if timing:
        with Progress(None, f"{name}: timing a few steps"):
            per_step, timed = time_per_step(scene)
        if timed:
            record["seconds_per_step"] = per_step
            record["estimated_seconds"] = per_step * cost.steps
    return record


def _stability(scene: Scene) -> dict:
    """Return the predicted stable dt (as ``mslab run`` computes it) and a warning when dt is above it."""
    from mslab.commands.run_checks import predicted_dt, prediction_line

    method, dt = scene.settings.method, scene.settings.dt
    predicted, _ = predicted_dt(scene, method)
    over = predicted is not None and not math.isnan(predicted) and dt > predicted
    return {"predicted_stable_dt": predicted if predicted is not None and math.isfinite(predicted) else None,
            "warning": prediction_line(method, dt, predicted) if over else None}


def line(record: dict) -> str:
    """``FILE: ok (10 particles, ...; 1000 steps, ...; about 0.2 s)``."""
    from mslab.budget import RunCost
    from mslab.progress import duration

    cost = RunCost(**record["cost"])
    if record["estimated_seconds"] is not None:
        when = f"; about {duration(record['estimated_seconds'])} (from a few timed steps)"
    else:
        when = ""
    from mslab.scene import plural

    size = f"{plural(record['n_particles'], 'particle')}, {plural(record['n_springs'], 'spring')}"
    return (f"{record['file']}: ok ({size}, "
            f"effects: {', '.join(record['effects']) or 'none'}; {record['method']}, dt = {record['dt']:g}, "
            f"t_end = {record['t_end']:g} s: {cost.describe()}{when})")


def run(args: argparse.Namespace) -> int:
    """Run ``mslab validate`` with the parsed ``args``; return the exit code."""
    from mslab.commands.common import write_json

    budget, budget_name = memory_budget(args)
    folder = out_path(args)
    if folder is not None:  # before any work, as `mslab run` does: the outputs could not be saved
        from mslab.files import output_problem

        problem = output_problem(folder)
        if problem:
            raise CommandError(problem, key="--out")
    results = []
    for name in args.files:
        overrides = {"method": args.method, "dt": args.dt, "t_end": args.t_end, "save_every": args.save_every}
        record = check(name, budget, budget_name, timing=not args.no_timing, overrides=overrides)
        results.append(record)
        if args.json:
            continue
        if record["ok"]:
            say(args, line(record))
            if record.get("warning"):  # as `mslab run` warns, before any work
                print(f"mslab: warning: {name}: {record['warning']}", file=sys.stderr)
        else:
            print(f"mslab: error: {record['error']}", file=sys.stderr)
    doc = {"files": results, "ok": all(r["ok"] for r in results)}
    if folder is not None:
        path = write_json(folder / "validate.json", doc)
        if not args.json:
            say(args, f"wrote {path}")
    if args.json:
        emit_json(doc)
    return 0 if doc["ok"] else 2
