"""Energy-ledger plots. Plotting only: every number comes from a Trajectory."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from mslab.trajectory import Trajectory


def plot_energy(traj: Trajectory, ax: Axes | None = None, components: bool = True,
                label: str | None = None) -> Axes:
    """Plot the energy ledger of one run over time: K, U, D, external work W and the total ``K + U + D - W``.

    Parameters
    ----------
    traj : Trajectory
    ax : matplotlib Axes, optional
    components : bool
        Draw K, U, D (and W_ext when a wind drives) as well as the total.
    label : str, optional
        Label of the total's line (default: the method's name).

    Returns
    -------
    ax
    """
    ax = ax if ax is not None else plt.gca()
    e = traj.energy
    if components:
        ax.plot(traj.t, e.kinetic, lw=1, label="kinetic K")
        ax.plot(traj.t, e.potential, lw=1, label="potential U")
        if np.any(e.dissipated):
            ax.plot(traj.t, e.dissipated, lw=1, label="dissipated D")
        if np.any(e.external):
            ax.plot(traj.t, e.external, lw=1, label="external work W")
    ax.plot(traj.t, e.total, lw=2, color="k" if components else None,
            label=label or f"total ({traj.stats.method})")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("energy [J]")
    ax.legend(loc="best", fontsize="small")
    return ax


def plot_energy_error(trajs: Sequence[Trajectory], ax: Axes | None = None) -> Axes:
    """Plot the relative error of the ledger total for several runs (log scale).

    Plots ``|E(t) - E(0)|`` divided by the run's energy scale
    (:meth:`mslab.simulate.Energy.relative_drift`: the largest kinetic energy in the first
    quarter of the run, since the zero of potential energy is arbitrary).

    Every other run is drawn dashed, so that runs whose curves coincide stay visible.

    Parameters
    ----------
    trajs : sequence of Trajectory
    """
    ax = ax if ax is not None else plt.gca()
    for i, tr in enumerate(trajs):
        drift = np.abs(tr.energy.relative_drift())
        # every other run dashed and on top: runs whose errors coincide (the two symplectic
        # Eulers, implicit Euler by Newton and by fixed point) stay visible as a pair
        ax.semilogy(tr.t[1:], np.maximum(drift[1:], 1e-17), label=tr.stats.method,
                    linestyle="-" if i % 2 == 0 else "--", zorder=2 + i % 2)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("relative energy error")
    ax.legend(loc="best", fontsize="small", ncol=2)
    return ax
