"""Plots: ``plot_*(..., ax=None) -> ax``; plotting only, no computation, never ``plt.show()``."""

from mslab.plots.energy import plot_energy, plot_energy_error

__all__ = ["plot_energy", "plot_energy_error"]
