"""``mslab precision SCENE``: convergence and work-precision of the methods, scipy on the same axes.

Runs every (method, dt) of a sweep on one scene, measures the error against the
reference solution (closed form or scipy DOP853 at 1e-12), counts the work and times the
runs; scipy's ``solve_ivp`` (RK45, DOP853, Radau, BDF) runs over a tolerance sweep on the
same forces. Prints a table and the fitted orders; ``--out DIR`` writes the figures
(error vs wall time, error vs force evaluations, error vs dt) and ``precision.json``.

``--jobs N`` runs the error runs in N processes, at most as many as the CPUs this process may
use (a larger N is capped to that count, as :func:`mslab.precision.work_precision` does); the
timing runs always run one at a time in the main process afterwards, so no timing shares the
machine with the sweep's other runs (other programs on the machine still count: for clean
timings keep it idle).

Ctrl-C keeps the methods already finished (every run's error and, with timing, its wall
time; one at a time when serial): they are printed, written with ``--out`` and named in the
line ``mslab: interrupted after K of N methods (kept: ...)``; the exit code is 130.
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING

from mslab.commands.common import (
    CommandError,
    add_common_options,
    count,
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


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab precision`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "precision", help="convergence and work-precision of the methods (scipy on the same axes)",
        description="Error against dt, force evaluations and wall time for each method on one scene, "
                    "with scipy's solve_ivp (RK45, DOP853, Radau, BDF) over a tolerance sweep.")
    p.add_argument("scene", metavar="SCENE", help="built-in scene name, TOML file, or 'oscillator'")
    p.add_argument("--methods", nargs="+", metavar="M",
                   help="methods (default: the course's; list: `mslab methods`)")
    p.add_argument("--dts", nargs="+", type=number(positive=True), metavar="DT",
                   help="steps (default: the scene's dt times 16, 8, 4, 2, 1); each must divide t_end")
    p.add_argument("--t-end", type=number(positive=True), default=None,
                   help="end time (default: the scene's)")
    p.add_argument("--scipy", nargs="*", metavar="S", default=None,
                   help="solve_ivp methods (default: RK45 DOP853 Radau BDF; give none to leave scipy out)")
    p.add_argument("--rtols", nargs="+", type=number(positive=True), metavar="RTOL",
                   help="scipy tolerance sweep")
    p.add_argument("--no-timing", action="store_true", help="errors and counts only (much faster)")
    p.add_argument("--repeats", type=count(1), default=3,
                   help="timed runs per record, minimum kept (default 3)")
    p.add_argument("--budget", type=number(minimum=0), default=1.0,
                   help="seconds of timed runs per record before stopping early (default 1)")
    p.add_argument("--jobs", type=count(1), default=1,
                   help="processes for the error runs, at most the CPU count (a larger N is capped "
                        "to it); timings stay serial (default 1)")
    add_common_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``mslab precision`` with the parsed ``args``; return the exit code."""
    from mslab import precision
    from mslab.integrators.base import get_method
    from mslab.simulate import step_count

    for rtol in args.rtols or ():  # scipy's own limits: > 100 eps (else it clamps with a warning), < 1
        if not 2.3e-14 <= rtol < 1:
            raise CommandError(f"{rtol:g} is not a tolerance; give numbers between 2.3e-14 and 1",
                               key="--rtols")
    scene = resolve_scene(args.scene)
    t_end = float(args.t_end if args.t_end is not None else scene.settings.t_end)
    if args.dts:
        dts = args.dts
    else:
        dts = precision.whole_dts([scene.settings.dt * 2 ** k for k in (4, 3, 2, 1, 0)], t_end)
    for dt in dts:
        try:
            step_count(t_end, dt)
        except ValueError as err:
            raise CommandError(str(err), key="--dts") from None
    methods = method_list(args.methods)
    scipy_methods = precision.SCIPY_METHODS if args.scipy is None else tuple(args.scipy)
    for s in scipy_methods:
        if s not in ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA"):
            raise CommandError(f"unknown solve_ivp method '{s}'; valid: RK45 RK23 DOP853 Radau BDF LSODA",
                               key="--scipy")
    from mslab.precision.runs import usable_cpus
    from mslab.precision.work_precision import PrecisionInterrupted

    jobs = min(args.jobs, usable_cpus())  # --jobs above the CPU count: capped to it

    try:
        records, stopped = precision.work_precision(
            scene, methods, dts, t_end, scipy_methods=scipy_methods,
            rtols=args.rtols or precision.SCIPY_RTOLS, timing=not args.no_timing, repeats=args.repeats,
            budget=args.budget, jobs=jobs, progress=None), None
    except PrecisionInterrupted as stop:  # Ctrl-C: the methods already finished are kept (and written)
        records, stopped = stop.records, stop
        methods = [m for m in methods if m in stop.methods]
    orders = precision.fitted_orders(records, ceiling=precision.error_ceiling(scene, t_end))
    expected = {m: get_method(m).order for m in methods}
    figures = _figures(args, records, orders, expected)
    doc = {"scene": scene.name, "t_end": t_end, "dts": dts, "reference": records[0]["reference"]
           if records else None, "records": records, "orders": orders, "expected_orders": expected,
           "figures": figures, "jobs": jobs}
    folder = out_dir(args)
    if folder is not None:
        write_json(folder / "precision.json", doc)
    if stopped is not None:
        kept = ", ".join(stopped.methods) or "none"
        written = f"; written to {folder}" if folder is not None else " (nothing written: no --out)"
        print(f"mslab: interrupted after {len(stopped.methods)} of {stopped.total} methods (kept: {kept})"
              f"{written}", file=sys.stderr)
    code = EXIT_INTERRUPTED if stopped is not None else 0
    if args.json:
        emit_json(doc)
        return code
    _print_tables(args, doc, methods)
    for f in figures:
        say(args, f"wrote {f}")
    return code


def _print_tables(args: argparse.Namespace, doc: dict, methods: list[str]) -> None:
    """Print the records, then the fitted orders of ``methods``."""
    rows = [[r["method"], fmt(r["dt"]), fmt(r["rtol"], ".0e"), r["steps"], r["n_force"], r["n_jac"],
             r["n_solve"], fmt(r["error"], ".2e"), fmt(r["error_rms"], ".2e"),
             ("-" if args.no_timing else fmt(r["wall_time"], ".3g")) if r["ok"] else "failed"]
            for r in doc["records"]]
    say(args, f"{doc['scene']}: t_end = {doc['t_end']:g}, reference = {doc['reference']}")
    header = ["method", "dt", "rtol", "steps", "n_force", "n_jac", "n_solve", "error", "error_rms",
              "wall_time [s]"]
    say(args, table(rows, header))
    if not args.no_timing:
        say(args, f"wall_time: stepping only, the minimum of up to {args.repeats} timed runs made after an "
                  "untimed run of the same method (compilation and first-call costs excluded)")
    local = {r["method"]: r["local_order"] for r in sorted(doc["records"], key=lambda r: -r["dt"])
             if r["solver"] == "mslab"}   # slope between the two smallest dts
    say(args, "orders: fitted over errors below a tenth of the solution's size; local = between the two "
              "smallest dts")
    def order(p: float | None):
        return "-" if p is None or not math.isfinite(p) else f"{p:.2f}"

    orders, expected = doc["orders"], doc["expected_orders"]
    say(args, table([[m, order(orders[m]), order(local[m]), expected[m]] for m in methods],
                    ["method", "fitted", "local", "expected"]))
    if any(not math.isfinite(orders[m]) for m in methods):
        say(args, "  (-: fewer than two errors in the asymptotic range; try smaller --dts)")


def _figures(args: argparse.Namespace, records: list[dict], orders: dict, expected: dict) -> list[str]:
    folder = out_dir(args)
    if folder is None or not records:  # (interrupted before any method finished: the JSON only)
        return []
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mslab.commands.common import save_figure
    from mslab.plots.precision import plot_convergence, plot_work_precision
    from mslab.precision import Convergence

    written = []
    for x, name in (("wall_time", "work_precision_time.png"), ("n_force", "work_precision_force.png")):
        if x == "wall_time" and args.no_timing:
            continue
        fig, ax = plt.subplots(figsize=(7, 5))
        plot_work_precision(records, ax=ax, x=x)
        ax.set_title(f"work-precision: error vs {'wall time' if x == 'wall_time' else 'force evaluations'}")
        written.append(str(save_figure(fig, folder / name)))
    fig, ax = plt.subplots(figsize=(7, 5))
    mslab_records = [r for r in records if r["solver"] == "mslab"]
    plot_convergence(Convergence(mslab_records, orders, expected), ax=ax)
    ax.set_title("convergence: error at t_end vs dt")
    written.append(str(save_figure(fig, folder / "convergence.png")))
    return written
