"""``make demo``: a short tour of mslab, written into ``out/``.

1. The spring chain under every course method: a table of steps, force evaluations,
   wall time and relative energy drift, and the energy of every run in one figure.
2. The cloth under implicit Euler (``mslab run cloth --animate gif``): data, figures and
   an animation.
3. The volume-collapse pair: the same soft cube with and without shear springs dropped on
   a plane; the one without shear springs loses its volume (lecture notes, §2.8).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import mslab  # noqa: E402
from mslab import interrupts, jit  # noqa: E402
from mslab.commands.common import save_figure  # noqa: E402
from mslab.plots import plot_energy_error  # noqa: E402
from mslab.progress import compile_notice  # noqa: E402
from mslab.scenes import chain  # noqa: E402


def chain_tour(out: Path, dt: float = 1e-3, t_end: float = 2.0) -> list:
    """Run the chain under every course method: print the table, save the energy figure, return the runs."""
    scene = chain(10, dim=2, stiffness=200.0)
    print(f"1. {scene.description}, undamped, under gravity: every course method, dt = {dt:g}, "
          f"t_end = {t_end:g}")
    print(f"   {'method':<20} {'steps':>6} {'n_force':>8} {'n_iter':>7} {'backend':>7} {'compile [s]':>11} "
          f"{'wall [s]':>9} {'energy drift':>13}")
    runs = []
    for method in mslab.COURSE_METHODS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", mslab.StabilityWarning)
            try:
                backend = chosen_backend(scene, method, round(t_end / dt))
                first = warm_up(scene, method, dt, backend)
                tr = mslab.simulate(scene, method, dt=dt, t_end=t_end, save_every=10, backend=backend)
            except mslab.InstabilityError as err:
                print(f"   {method:<20} {err}")
                continue
        s = tr.stats
        drift = float(np.abs(tr.energy.relative_drift()).max())
        print(f"   {method:<20} {s.steps:>6} {s.n_force:>8} {s.n_iter:>7} {backend:>7} {first:>11.3f} "
              f"{s.wall_time:>9.3f} {drift:>13.2e}")
        runs.append(tr)
    print("   backend: what simulate(backend='auto') takes for the run: the compiled loop only when the "
          "run is long enough\n   to repay numba compilation or loading (these short runs are not); "
          "compile: the seconds of a first 10-step run\n   on that backend (first-call costs); wall: the "
          "stepping of the run itself, measured after it")
    fig, ax = plt.subplots(figsize=(8, 5))
    plot_energy_error(runs, ax=ax)
    ax.set_title(f"Relative energy error on the chain, dt = {dt:g}")
    path = save_figure(fig, out / "chain_energy.png")
    print(f"   figure: {path}")
    return runs


def chosen_backend(scene: mslab.Scene, method: str, n_steps: int) -> str:
    """Return the backend ``simulate(backend="auto")`` takes for ``n_steps`` of ``method`` on ``scene``.

    The warm-up run then pays that backend's first-call costs (numba compiles or loads only
    where the timed run repays it), so the timed run's wall time holds none of them.
    """
    from mslab import fast, jit

    integrator = mslab.get_method(method)
    applies = fast.unsupported(scene.system, integrator) is None
    compiled = applies and jit.available() and fast.worth_compiling(scene.system, integrator, n_steps)
    return "numba" if compiled else "numpy"


def warm_up(scene: mslab.Scene, method: str, dt: float, backend: str, steps: int = 10) -> float:
    """Return the seconds of a first short run of ``method`` (compilation, caches).

    They are kept out of the wall column.
    """
    start = time.perf_counter()
    try:
        mslab.simulate(scene, method, dt=dt, t_end=steps * dt, save_every=steps, progress=False,
                       backend=backend)
    except mslab.InstabilityError:
        pass
    return time.perf_counter() - start


def cloth_tour(out: Path) -> None:
    """Run ``mslab run cloth --animate gif`` into ``out/cloth``."""
    from mslab.cli import main as cli_main

    print("2. cloth under implicit Euler, with an animation (mslab run cloth --animate gif)")
    code = cli_main(["run", "cloth", "--animate", "gif", "--out", str(out / "cloth")])
    if code:
        raise SystemExit(code)


def volume_tour(out: Path) -> None:
    """Drop the soft cubes with and without shear springs; plot their convex-hull volume."""
    from scipy.spatial import ConvexHull

    print("3. volume collapse: a soft cube dropped on a plane, with and without shear springs")
    fig, ax = plt.subplots(figsize=(7, 4))
    for name in ("jelly_cube", "cube_no_shear"):
        scene = mslab.load_scene(name)
        tr = mslab.simulate(scene)
        volume = np.array([ConvexHull(x).volume for x in tr.x])
        print(f"   {name:<14} {scene.settings.method}, dt = {scene.settings.dt:g}: "
              f"volume at the end / at the start = {volume[-1] / volume[0]:.2f}")
        ax.plot(tr.t, volume / volume[0], label=name)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("convex-hull volume / initial volume")
    ax.set_title("Mass-spring systems do not preserve volume: topology decides")
    ax.legend()
    print(f"   figure: {save_figure(fig, out / 'volume_collapse.png')}")


def main(argv: list[str] | None = None) -> int:
    """Run the three tours into ``--out`` (default ``out/``); return the exit code.

    Compilations are announced on stderr; Ctrl-C ends with exit code 130 and one line, at any
    moment (the files written before it are complete).
    """
    parser = argparse.ArgumentParser(description="mslab tour")
    parser.add_argument("--out", default="out")
    args = parser.parse_args(argv)
    out = Path(args.out)
    announcer = jit.announce_with(compile_notice)
    with interrupts.command_line():
        try:
            out.mkdir(parents=True, exist_ok=True)
            chain_tour(out)
            cloth_tour(out)
            volume_tour(out)
            print(f"All outputs are in {out}/")
            code = 0
        except KeyboardInterrupt:
            interrupts.finishing()
            sys.stdout.flush()
            print(f"mslab: interrupted; the files written so far in {out}/ are complete", file=sys.stderr)
            code = interrupts.EXIT_INTERRUPTED
        except SystemExit as stop:  # the cloth tour's command ended early (interrupted: 130)
            code = int(stop.code or 0)
        finally:
            interrupts.finishing()
            jit.announce_with(announcer)
    return interrupts.leave(code)


if __name__ == "__main__":
    raise SystemExit(main())
