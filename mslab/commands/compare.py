"""``mslab compare SCENE``: every course method on one scene, energy drift side by side.

Each method runs the scene with the same dt and t_end; the table lists the steps, force
evaluations, wall time, the peak and final relative error of the energy ledger
``K + U + D``, its drift rate and the verdict "bounded" or "drifting" (rule:
:func:`mslab.precision.drift_verdict`). ``--out DIR`` writes ``energy_drift.png`` (relative
energy error over time, log scale) and ``compare.json``.

Undamped scenes show it best (the built-in ``chain``): the exact total energy is then
constant, and every change is the method's. The default run is ten times the scene's
``t_end``: over a short run a slow drift (midpoint, Heun) hides in the oscillation of
the energy error and reads as bounded.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from mslab.commands.common import (
    CommandError,
    add_common_options,
    emit_json,
    fmt,
    method_list,
    number,
    out_dir,
    resolve_scene,
    say,
    table,
    write_json,
)
from mslab.interrupts import EXIT_INTERRUPTED

if TYPE_CHECKING:
    import argparse
    from pathlib import Path

    from mslab.scene import Scene

#: default run length, in units of the scene's t_end: a verdict needs many oscillations
LONG_RUN = 10


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab compare`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "compare", help="run the course's methods on one scene: work, wall time, energy drift",
        description="Energy drift of each method on one scene: relative error of K + U + D over time, "
                    "drift rate and a bounded-vs-drifting verdict.")
    p.add_argument("scene", metavar="SCENE", help="built-in scene name, TOML file, or 'oscillator'")
    p.add_argument("--methods", nargs="+", metavar="M",
                   help="methods (default: every course method; list: `mslab methods`)")
    p.add_argument("--dt", type=number(positive=True), default=None, help="step (default: the scene's)")
    p.add_argument("--t-end", type=number(positive=True), default=None,
                   help="end time (default: 10 times the scene's: drift shows only over long runs)")
    add_common_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``mslab compare`` with the parsed ``args``; return the exit code."""
    from mslab.precision import energy_drift
    from mslab.precision.drift import DriftInterrupted
    from mslab.simulate import step_count

    scene = resolve_scene(args.scene)
    dt = float(args.dt if args.dt is not None else scene.settings.dt)
    if args.t_end is not None:
        t_end = float(args.t_end)
    else:  # ten times the scene's run, rounded to a whole number of steps
        t_end = dt * max(1, round(LONG_RUN * scene.settings.t_end / dt))
    try:
        step_count(t_end, dt)
    except ValueError as err:
        raise CommandError(str(err), key="--dt") from None
    methods = method_list(args.methods)
    try:
        drifts, stopped = energy_drift(scene, methods, dt, t_end, progress=None), False  # a bar by the clock
    except DriftInterrupted as stop:  # Ctrl-C: the methods already finished are kept (and written)
        drifts, stopped = stop.finished, True
    records = [d.as_record() for d in drifts.values()]
    figures = []
    folder = out_dir(args)
    if folder is not None:
        figures.append(str(_figure(scene, drifts, dt, folder)))
    doc = {"scene": scene.name, "dt": dt, "t_end": t_end, "methods": records, "figures": figures}
    if folder is not None:
        write_json(folder / "compare.json", doc)
    if stopped:
        kept = ", ".join(drifts) or "none"
        written = f"; written to {folder}" if folder is not None else " (nothing written: no --out)"
        print(f"mslab: interrupted after {len(drifts)} of {len(methods)} methods (kept: {kept}){written}",
              file=sys.stderr)
    if args.json:
        emit_json(doc)
        return EXIT_INTERRUPTED if stopped else 0
    rows = []
    for r in records:
        rows.append([r["method"], r["steps"], r["n_force"], fmt(r["wall_time"], ".3g"),
                     fmt(r["max_error"], ".2e"), fmt(r["final_error"], ".2e"), fmt(r["drift_rate"], ".2e"),
                     verdict_text(r, dt)])
    say(args, f"{scene.name}: dt = {dt:g}, t_end = {t_end:g}")
    say(args, table(rows, ["method", "steps", "n_force", "wall_time [s]", "max |dE|/E", "final dE/E",
                           "drift [1/s]", "verdict"]))
    say(args, "wall_time: stepping only, after a 10-step warm-up run of each method (compilation and "
              "first-call costs excluded); steps: up to and including a failing step")
    for r in records:
        if r["stopped"] == "no convergence":
            say(args, f"  {r['method']}: {r['failure']}")
    for f in figures:
        say(args, f"wrote {f}")
    return EXIT_INTERRUPTED if stopped else 0


def verdict_text(record: dict, dt: float) -> str:
    """Return the verdict of one drift record in words.

    ``bounded``, ``drifting``, ``drifting: blew up at step 7 (t = 0.07)`` or ``no convergence
    at step 1 (t = 0.01)``: a failed iteration is not an energy drift.
    """
    if record["complete"]:
        return record["verdict"]
    step = record["steps"]
    where = f"at step {step} (t = {step * dt:.4g})"
    if record["stopped"] == "no convergence":
        return f"no convergence {where}"
    return f"{record['verdict']}: blew up {where}"


def _figure(scene: Scene, drifts: dict, dt: float, folder: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mslab.commands.common import save_figure
    from mslab.plots.precision import plot_energy_drift

    fig, ax = plt.subplots(figsize=(7, 5))
    plot_energy_drift(drifts, ax=ax)
    ax.set_title(f"{scene.name}: relative energy error, dt = {dt:g}")
    return save_figure(fig, folder / "energy_drift.png")
