"""``mslab run SCENE``: simulate one scene, print work and energy ledger, save data and figures.

Exit codes: 0 the run finished; 2 a mistake in the scene file or the options (one line
``mslab: error: FILE: KEY: reason``); 3 the run blew up (InstabilityError) or an implicit
method's iteration did not converge (ConvergenceError): one line naming step, time and dt,
and the part computed so far is saved when ``--out`` is given; 130 interrupted (Ctrl-C),
what was computed is saved when ``--out`` is given.

With ``--out DIR`` (or ``--animate``, default folder ``out/SCENE``) it writes
``SCENE.npz`` (t, x, v, energies, springs, stats), ``SCENE_energy.png`` (the ledger),
``SCENE_final.png`` (final configuration) and with ``--animate`` ``SCENE.gif`` (or
``.mp4`` with ``--animate mp4`` where ffmpeg exists). Every file is written to a temporary
name and renamed, so a file that exists is complete.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from mslab.commands.common import CommandError, add_common_options, atomic_write, emit_json, out_dir, say

#: exit code of a run that blew up or whose implicit iteration failed
EXIT_UNSTABLE = 3
#: exit code of an interrupted run (128 + SIGINT)
EXIT_INTERRUPTED = 130


def register(subparsers) -> None:
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
    add_common_options(p)
    p.set_defaults(func=run)


def add_settings_options(p) -> None:
    """``--method --dt --t-end --save-every``: override the scene file's [run] settings."""
    p.add_argument("--method", default=None, help="integrator (see `mslab stability all` for the list)")
    p.add_argument("--dt", type=float, default=None, help="time step [s]")
    p.add_argument("--t-end", dest="t_end", type=float, default=None, help="end time [s]")
    p.add_argument("--save-every", dest="save_every", type=int, default=None, help="keep every n-th step")


def predicted_dt(scene, method: str) -> float | None:
    """Predicted largest stable step from :mod:`mslab.stability`, or None if unavailable."""
    try:
        from mslab.stability import max_stable_dt
    except ImportError:
        return None
    try:
        return float(max_stable_dt(scene, method))
    except Exception:  # noqa: BLE001 - a prediction must never stop a run
        return None


def energy_summary(traj) -> dict:
    """Energy ledger at the start and end of a trajectory, and its relative drift."""
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
        "relative_drift": float(drift[-1]),
        "max_abs_relative_drift": float(np.max(np.abs(drift))),
    }


def save_npz(path: Path, traj, scene) -> Path:
    """The trajectory, its ledger and the scene's topology as one ``.npz`` (atomically)."""
    springs = scene.springs()
    data = {
        "t": traj.t,
        "x": traj.x,
        "v": traj.v,
        "kinetic": traj.energy.kinetic,
        "potential": traj.energy.potential,
        "dissipated": traj.energy.dissipated,
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


def save_outputs(folder: Path, traj, scene, animate: str | None) -> dict:
    """Write the data, the two figures and (optionally) the animation; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mslab.commands.common import save_figure
    from mslab.plots import plot_configuration, plot_energy

    name = scene.name
    files = {"data": save_npz(folder / f"{name}.npz", traj, scene)}
    if len(traj.t) == 0:
        return files
    fig, ax = plt.subplots(figsize=(7, 4))
    plot_energy(traj, ax=ax)
    ax.set_title(f"{name}: energy ledger ({traj.stats.method}, dt = {traj.stats.dt:g})")
    files["energy_figure"] = save_figure(fig, folder / f"{name}_energy.png")
    springs = scene.springs()
    pairs = springs.springs if springs is not None else np.empty((0, 2), np.int64)
    colliders = [e for e in scene.system.effects if e.name in ("plane", "sphere")]
    ax = plot_configuration(traj.x[-1], pairs, pinned=scene.system.pinned, colliders=colliders)
    ax.set_title(f"{name} at t = {traj.t[-1]:.4g} s ({traj.stats.method})")
    files["final_figure"] = save_figure(ax.figure, folder / f"{name}_final.png")
    if animate:
        from matplotlib import animation as mpl_animation

        from mslab.plots import animate as write_animation

        if animate == "mp4" and not mpl_animation.writers.is_available("ffmpeg"):
            raise CommandError("ffmpeg not found; use --animate gif", key="--animate")
        files["animation"] = atomic_write(
            folder / f"{name}.{animate}", lambda tmp: write_animation(traj, scene, tmp)
        )
    return files


def _report(args, scene, traj, predicted, files, notes) -> dict:
    s = traj.stats
    doc = {
        "scene": scene.name,
        "description": scene.description,
        "n_particles": scene.n_particles,
        "dim": scene.dim,
        "effects": scene.effects,
        "method": s.method,
        "dt": s.dt,
        "t_end": float(traj.t[-1]) if len(traj.t) else 0.0,
        "complete": traj.complete,
        "predicted_stable_dt": predicted,
        "stats": s.as_dict(),
        "energy": energy_summary(traj),
        "files": {k: str(v) for k, v in files.items()},
        "notes": notes,
    }
    if args.json:
        return doc
    say(
        args,
        f"{scene.name}: {scene.n_particles} particles, dim {scene.dim}, effects: {', '.join(scene.effects)}",
    )
    say(
        args,
        f"method {s.method}, dt = {s.dt:g}, {s.steps} steps to t = {doc['t_end']:g} s"
        + ("" if traj.complete else " (incomplete)"),
    )
    say(
        args,
        f"work: n_force = {s.n_force}, n_jac = {s.n_jac}, n_solve = {s.n_solve}, n_iter = {s.n_iter}, "
        f"wall time = {s.wall_time:.3f} s",
    )
    e = doc["energy"]
    if e:
        say(
            args,
            f"energy ledger K + U + D: {e['initial_total']:.6g} -> {e['final_total']:.6g} J "
            f"(K = {e['final_kinetic']:.4g}, U = {e['final_potential']:.4g}, "
            f"D = {e['final_dissipated']:.4g}); "
            f"relative drift {e['relative_drift']:.3e}, max |drift| {e['max_abs_relative_drift']:.3e}",
        )
    for key, path in files.items():
        say(args, f"wrote {key.replace('_', ' ')}: {path}")
    return doc


def run(args) -> int:
    from mslab.errors import InstabilityError, StabilityWarning
    from mslab.scenes.loader import load_scene
    from mslab.simulate import SimulationInterrupted, simulate

    scene = load_scene(
        args.scene, method=args.method, dt=args.dt, t_end=args.t_end, save_every=args.save_every
    )
    method = scene.settings.method
    folder = out_dir(args, default=f"out/{scene.name}" if args.animate else None)
    notes: list[str] = []

    # -- predicted stable step (mslab.stability.max_stable_dt) ------------------------------------------
    predicted = predicted_dt(scene, method)
    if predicted is not None and not args.json:
        if predicted == np.inf:
            limit, verdict = "no limit (A-stable)", ""
        elif predicted == 0:
            limit, verdict = "none: unstable at every dt on this scene (undamped oscillations grow)", ""
        else:
            above = scene.settings.dt > predicted
            limit, verdict = f"{predicted:.4g} s", " (dt is above it)" if above else " (dt is below it)"
        say(args, f"predicted stable dt for {method}: {limit}{verdict}")
    # ----------------------------------------------------------------------------------------------------

    if not args.json:
        say(args, f"running {method} on {scene.name} ...")
        sys.stdout.flush()
    code, failure = 0, ""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StabilityWarning)
        try:
            traj = simulate(scene, progress=None, stable_dt=predicted)
        except SimulationInterrupted as stop:
            traj, code = stop.trajectory, EXIT_INTERRUPTED
        except InstabilityError as err:
            if err.trajectory is None:
                raise
            traj, code = err.trajectory, EXIT_UNSTABLE
            failure = str(err).splitlines()[0]
            notes.append(failure)
    for w in caught:
        if issubclass(w.category, StabilityWarning):
            notes.append(str(w.message))
            print(f"mslab: warning: {w.message}", file=sys.stderr)
    files = save_outputs(folder, traj, scene, args.animate if code == 0 else None) if folder else {}
    doc = _report(args, scene, traj, predicted, files, notes)
    if args.json:
        emit_json(doc)
    if code == EXIT_UNSTABLE:
        print(f"mslab: error: {failure}", file=sys.stderr)
    elif code == EXIT_INTERRUPTED:
        saved = f"; saved {len(traj.t)} samples to {files['data']}" if files else " (nothing saved: no --out)"
        t_last = traj.t[-1] if len(traj.t) else 0.0
        print(f"mslab: interrupted at t = {t_last:.6g} s{saved}", file=sys.stderr)
    return code
