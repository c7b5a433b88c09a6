"""``mslab run SCENE``: simulate one scene, print work and energy ledger, save data and figures.

Cheap checks come first: the options (``--animate`` and the tool it needs, ffmpeg or
Pillow; ``--max-memory``), the scene file, and the run's size. Every run announces its
cost before it starts (steps, saved samples and the memory they take) and is refused, in
one line naming the ``save_every`` or ``t_end`` that would fit, when its saved data exceed
the memory budget (default: half the available memory). The predicted stable dt (an
eigenvalue analysis) is skipped for A-stable methods and above 5000 unknowns, as in
``simulate``, with a note saying so. On a terminal a progress bar appears once the run has
taken about 2 s, with an estimate of the time from the first steps; warnings are printed
when they arise.

Exit codes: 0 the run finished; 2 a mistake in the scene file or the options (one line
``mslab: error: FILE: KEY: reason``), nothing computed, nothing written; 3 the run blew up
(InstabilityError) or an implicit method's iteration did not converge (ConvergenceError):
one line naming step, time and dt, and the part computed so far is saved when ``--out`` is
given; 130 interrupted (Ctrl-C): what was computed is saved when ``--out`` is given, and
nothing at all (no empty folder) when the run had not started.

With ``--out DIR`` (or ``--animate``, default folder ``out/SCENE``) it writes
``SCENE.npz`` (t, x, v, energies, springs, stats), ``SCENE_energy.png`` (the ledger),
``SCENE_final.png`` (final configuration) and with ``--animate`` ``SCENE.gif`` (or
``.mp4`` with ``--animate mp4`` where ffmpeg exists). Every file is written to a temporary
name and renamed, so a file that exists is complete.
"""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from mslab.commands.common import (
    CommandError,
    add_budget_option,
    add_common_options,
    add_settings_options,
    atomic_write,
    emit_json,
    memory_budget,
    out_path,
    say,
)
from mslab.commands.run_checks import animation_problem, predicted_dt, prediction_line
from mslab.interrupts import phase

if TYPE_CHECKING:
    import argparse

    from mslab.budget import RunCost
    from mslab.scenes.builder import Scene
    from mslab.trajectory import Trajectory

#: exit code of a run that blew up or whose implicit iteration failed
EXIT_UNSTABLE = 3
#: exit code of an interrupted run (128 + SIGINT)
EXIT_INTERRUPTED = 130
#: room for the figures besides the saved data (the .npz is at most its raw size)
OUTPUT_EXTRA_BYTES = 2**20


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab run`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "run",
        help="simulate one scene (built-in name or TOML file)",
        description="Simulate a scene and print the work counters and the energy ledger.",
        epilog="exit codes: 0 done, 2 bad scene file or option, 3 unstable / no convergence, 130 interrupted",
    )
    p.add_argument("scene", metavar="SCENE", help="built-in scene name (see `mslab scenes`) or a .toml file")
    add_settings_options(p)
    p.add_argument(
        "--animate",
        nargs="?",
        const="gif",
        choices=("gif", "mp4"),
        default=None,
        help="also write an animation (GIF through Pillow; mp4 needs ffmpeg)",
    )
    add_budget_option(p)
    add_common_options(p)
    p.set_defaults(func=run)


def drift_words(drift: np.ndarray | float, method: str) -> str:
    """Say what the relative change of the ledger ``K + U + D - W_ext`` over a run means.

    ``drift``: the relative drift at each saved sample (a number: the final one only). Below
    1e-6 nothing is said. A drift whose largest size in the second half of the run is within
    1.5 times that of the first half, and that oscillates (its path is more than four times
    its range), is bounded (a symplectic method's energy error oscillates; a steady drift
    doubles from the middle to the end);
    otherwise its sign says whether the method adds energy or damps it numerically (a
    one-sided loss that levels off, implicit Euler on a cloth coming to rest, is damping).
    """
    series = np.atleast_1d(np.asarray(drift, dtype=float))
    final = float(series[-1]) if series.size else math.nan
    if not math.isfinite(final) or abs(final) <= 1e-6:
        return ""
    if series.size >= 4 and np.all(np.isfinite(series)):
        half = series.size // 2
        early, late = np.abs(series[:half + 1]).max(), np.abs(series[half:]).max()
        size = np.abs(series).max()
        # oscillating, not settling: the path travelled is several times the range covered
        oscillates = np.abs(np.diff(series)).sum() > 4.0 * (series.max() - series.min())
        if late <= 1.5 * early and oscillates:
            return (f" (bounded: the ledger oscillates within +-{size:.1e} without growing, "
                    f"{method}'s energy error)")
    if final < 0:
        return f" (the ledger lost energy: numerical damping of {method})"
    return f" (the ledger gained energy: {method} adds energy)"


def energy_summary(traj: Trajectory) -> dict:
    """Return the energy ledger at the start and end of a trajectory, and its relative drift."""
    e = traj.energy
    drift = e.relative_drift() if len(traj.t) else np.zeros(0)
    if not len(traj.t):
        return {}
    return {
        "initial_total": float(e.total[0]),
        "final_total": float(e.total[-1]),
        "final_kinetic": float(e.kinetic[-1]),
        "final_potential": float(e.potential[-1]),
        "final_dissipated": float(e.dissipated[-1]),
        "final_external": float(e.external[-1]),
        "relative_drift": float(drift[-1]),
        "max_abs_relative_drift": float(np.max(np.abs(drift))),
    }


def save_npz(path: Path, traj: Trajectory, scene: Scene) -> Path:
    """Save the trajectory, its ledger and the scene's topology as one ``.npz`` (atomically)."""
    springs = scene.springs()
    data = {
        "t": traj.t,
        "x": traj.x,
        "v": traj.v,
        "kinetic": traj.energy.kinetic,
        "potential": traj.energy.potential,
        "dissipated": traj.energy.dissipated,
        "external": traj.energy.external,
        "total": traj.energy.total,
        "complete": np.bool_(traj.complete),
        "springs": springs.springs if springs is not None else np.empty((0, 2), np.int64),
        "spring_kind": scene.spring_kind,
        "mass": scene.system.mass,
        "pinned": scene.system.pinned,
        "method": np.str_(traj.stats.method),
        "dt": traj.stats.dt,
        "steps": traj.stats.steps,
        "n_force": traj.stats.n_force,
        "n_jac": traj.stats.n_jac,
        "n_solve": traj.stats.n_solve,
        "n_iter": traj.stats.n_iter,
        "wall_time": traj.stats.wall_time,
    }
    return atomic_write(path, lambda tmp: np.savez_compressed(tmp, **data))


def save_outputs(folder: Path, traj: Trajectory, scene: Scene, animate: str | None,
                 files: dict | None = None) -> dict:
    """Write the data, the two figures and (optionally) the animation; returns their paths.

    ``files`` (filled as each file is written) tells an interrupted caller what exists.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mslab.commands.common import save_figure
    from mslab.files import file_stem
    from mslab.plots import plot_configuration, plot_energy

    name = file_stem(scene.name)  # a name, never a path: every file stays inside ``folder``
    files = {} if files is None else files
    files["data"] = save_npz(folder / f"{name}.npz", traj, scene)
    phase("saving")  # (tests: a Ctrl-C while saving)
    if len(traj.t) == 0:
        return files
    fig, ax = plt.subplots(figsize=(7, 4))
    plot_energy(traj, ax=ax)
    ax.set_title(f"{name}: energy ledger ({traj.stats.method}, dt = {traj.stats.dt:g})")
    files["energy_figure"] = save_figure(fig, folder / f"{name}_energy.png")
    springs = scene.springs()
    pairs = springs.springs if springs is not None else np.empty((0, 2), np.int64)
    colliders = [e for e in scene.system.effects if e.outline() is not None]
    ax = plot_configuration(traj.x[-1], pairs, pinned=scene.system.pinned, colliders=colliders)
    ax.set_title(f"{name} at t = {traj.t[-1]:.4g} s ({traj.stats.method})")
    files["final_figure"] = save_figure(ax.figure, folder / f"{name}_final.png")
    if animate:
        from mslab.plots import animate as write_animation
        from mslab.progress import Progress

        with Progress(None, f"writing {name}.{animate}", unit="frame") as bar:
            files["animation"] = atomic_write(
                folder / f"{name}.{animate}", lambda tmp: write_animation(traj, scene, tmp, progress=bar)
            )
    return files


def _report(args: argparse.Namespace, scene: Scene, traj: Trajectory, predicted: float | None, files: dict,
            notes: list[str], cost: RunCost) -> dict:
    s = traj.stats
    t_last = float(traj.t[-1]) if len(traj.t) else 0.0
    stopped = None if traj.complete else {"step": s.steps, "t": s.steps * s.dt}
    doc = {
        "scene": scene.name,
        "description": scene.description,
        "n_particles": scene.n_particles,
        "dim": scene.dim,
        "effects": scene.effects,
        "method": s.method,
        "dt": s.dt,
        "t_end": cost.t_end,
        "complete": traj.complete,
        "stopped_at": stopped,
        "t_last_saved": t_last,
        "cost": cost.as_dict(),
        "predicted_stable_dt": predicted,
        "stats": s.as_dict(),
        "energy": energy_summary(traj),
        "files": {k: str(v) for k, v in files.items()},
        "notes": notes,
    }
    if args.json:
        return doc
    if traj.complete:
        say(args, f"method {s.method}, dt = {s.dt:g}: {s.steps} steps to t = {cost.t_end:g} s")
    else:
        say(args, f"method {s.method}, dt = {s.dt:g}: stopped at step {s.steps} of {cost.steps} "
                  f"(t = {s.steps * s.dt:.6g} s of {cost.t_end:g} s); "
                  f"last saved sample at t = {t_last:.6g} s")
    say(
        args,
        f"work: n_force = {s.n_force}, n_jac = {s.n_jac}, n_solve = {s.n_solve}, n_iter = {s.n_iter}, "
        f"wall time = {s.wall_time:.3f} s" + ("" if traj.complete else f" (to step {s.steps})"),
    )
    e = doc["energy"]
    if e:
        driven = bool(e["final_external"])  # a wind: the ledger subtracts the work it put in
        say(
            args,
            f"energy ledger K + U + D{' - W_ext' if driven else ''}: "
            f"{e['initial_total']:.6g} -> {e['final_total']:.6g} J "
            f"(K = {e['final_kinetic']:.4g}, U = {e['final_potential']:.4g}, "
            f"D = {e['final_dissipated']:.4g}"
            + (f", W_ext = {e['final_external']:.4g}" if driven else "") + "); "
            f"relative drift {e['relative_drift']:.3e}, max |drift| {e['max_abs_relative_drift']:.3e}"
            + drift_words(traj.energy.relative_drift(), s.method),
        )
    for key, path in files.items():
        say(args, f"wrote {key.replace('_', ' ')}: {path}")
    return doc


def _simulate(args: argparse.Namespace, scene: Scene, method: str, cost: RunCost, predicted: float | None,
              notes: list[str]) -> tuple[Trajectory, int, str]:
    """Run the scene with progress by the clock and warnings as they arise (added to ``notes``).

    Return the trajectory (partial when the run stopped), the exit code and the failure's line.
    """
    from mslab.errors import InstabilityError, StabilityWarning
    from mslab.progress import Progress, duration
    from mslab.simulate import SimulationInterrupted, simulate

    def estimate(total: float, done: int) -> None:
        bar.write(f"estimate: about {duration(total)} for {cost.steps} steps (from {bar.measured()} "
                  f"steps after the first)", file=sys.stdout)

    code, failure = 0, ""
    bar = Progress(cost.steps, method, on_estimate=None if args.json else estimate)
    with warnings.catch_warnings():
        warnings.simplefilter("always", StabilityWarning)
        shown = warnings.showwarning

        def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                 file: TextIO | None = None, line: str | None = None):
            if not issubclass(category, StabilityWarning):
                return shown(message, category, filename, lineno, file, line)
            notes.append(str(message))
            if not args.json:
                bar.write(f"mslab: warning: {message}")

        warnings.showwarning = show
        try:
            traj = simulate(scene, progress=bar, stable_dt=None if predicted == math.inf else predicted)
        except SimulationInterrupted as stop:
            traj, code = stop.trajectory, EXIT_INTERRUPTED
        except InstabilityError as err:
            if err.trajectory is None:
                raise
            traj, code = err.trajectory, EXIT_UNSTABLE
            failure = str(err).splitlines()[0]
            notes.append(failure)
        finally:
            bar.close()
    return traj, code, failure


def run(args: argparse.Namespace) -> int:
    """Run ``mslab run`` with the parsed ``args``; return the exit code."""
    # -- cheap checks first: options, environment, tools, the scene file, the run's size ------------
    from mslab import fast, jit
    from mslab.budget import memory_problem, run_cost, size_text
    from mslab.scenes.loader import load_scene

    fast.check_backend(None)  # $MSLAB_BACKEND and $MSLAB_THREADS: ValueError, one line
    jit.thread_count(None)
    problem = animation_problem(args.animate)
    if problem:
        raise CommandError(problem, key="--animate")
    budget, budget_name = memory_budget(args)
    scene = load_scene(args.scene, max_bytes=budget, method=args.method, dt=args.dt, t_end=args.t_end,
                       save_every=args.save_every)
    method = scene.settings.method
    cost = run_cost(scene)
    problem = memory_problem(cost, budget, budget_name)
    if problem:
        raise CommandError(problem, where=str(args.scene), key="run")
    from mslab.files import file_stem

    folder = out_path(args, default=f"out/{file_stem(scene.name)}" if args.animate else None)
    if folder is not None:  # found now, not after the run: its results would be lost
        from mslab.files import output_problem

        problem = output_problem(folder, cost.bytes_saved + OUTPUT_EXTRA_BYTES)
        if problem:
            raise CommandError(problem, key="--out")
    notes: list[str] = []
    if not args.json:
        say(args, f"{scene.name}: {scene.n_particles} particles, dim {scene.dim}, "
                  f"effects: {', '.join(scene.effects)}")
        fits = f" (budget {size_text(budget)})" if budget is not None else ""
        say(args, f"cost: {cost.describe()}{fits}")

    # -- predicted stable step: only where it can change something ------------------------------------
    try:
        predicted, skipped = predicted_dt(scene, method)
    except KeyboardInterrupt:
        print("mslab: interrupted before the run started: nothing computed, nothing written",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    if skipped:
        notes.append(skipped)
    if not args.json:
        say(args, skipped or prediction_line(method, scene.settings.dt, predicted))
        say(args, f"running {method} on {scene.name} ...")
        sys.stdout.flush()

    traj, code, failure = _simulate(args, scene, method, cost, predicted, notes)

    # -- outputs ---------------------------------------------------------------------------------------
    files: dict = {}
    try:
        if folder is not None:
            save_outputs(folder, traj, scene, args.animate if code == 0 else None, files)
    except KeyboardInterrupt:
        written = ", ".join(str(p) for p in files.values()) or "nothing"
        print(f"mslab: interrupted while writing the outputs; complete files: {written}", file=sys.stderr)
        return EXIT_INTERRUPTED
    doc = _report(args, scene, traj, predicted, files, notes, cost)
    if args.json:
        emit_json(doc)
    if code == EXIT_UNSTABLE:
        print(f"mslab: error: {failure}", file=sys.stderr)
    elif code == EXIT_INTERRUPTED:
        saved = f"; saved {len(traj.t)} samples to {files['data']}" if files else " (nothing saved: no --out)"
        t_last = traj.t[-1] if len(traj.t) else 0.0
        print(f"mslab: interrupted at t = {t_last:.6g} s{saved}", file=sys.stderr)
    return code
