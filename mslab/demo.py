"""``make demo``: a short tour of mslab, written into ``out/``.

1. The spring chain under every course method: a table of steps, force evaluations,
   wall time and relative energy drift, and the energy of every run in one figure.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import mslab  # noqa: E402
from mslab.commands.common import save_figure  # noqa: E402
from mslab.plots import plot_energy_error  # noqa: E402
from mslab.scenes import chain  # noqa: E402


def chain_tour(out: Path, dt: float = 1e-3, t_end: float = 2.0) -> list:
    scene = chain(10, dim=2, stiffness=200.0)
    print(f"1. {scene.description}, undamped, under gravity: every course method, dt = {dt:g}, "
          f"t_end = {t_end:g}")
    print(f"   {'method':<20} {'steps':>6} {'n_force':>8} {'n_iter':>7} {'wall [s]':>9} {'energy drift':>13}")
    runs = []
    for method in mslab.COURSE_METHODS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", mslab.StabilityWarning)
            try:
                tr = mslab.simulate(scene, method, dt=dt, t_end=t_end, save_every=10)
            except mslab.InstabilityError as err:
                print(f"   {method:<20} {err}")
                continue
        s = tr.stats
        drift = float(np.abs(tr.energy.relative_drift()).max())
        print(f"   {method:<20} {s.steps:>6} {s.n_force:>8} {s.n_iter:>7} {s.wall_time:>9.3f} {drift:>13.2e}")
        runs.append(tr)
    fig, ax = plt.subplots(figsize=(8, 5))
    plot_energy_error(runs, ax=ax)
    ax.set_title(f"Relative energy error on the chain, dt = {dt:g}")
    path = save_figure(fig, out / "chain_energy.png")
    print(f"   figure: {path}")
    return runs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="mslab tour")
    parser.add_argument("--out", default="out")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    chain_tour(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
