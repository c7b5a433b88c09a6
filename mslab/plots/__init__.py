"""Plots: ``plot_*(..., ax=None) -> ax``; plotting only, no computation, never ``plt.show()``."""

from mslab.plots.energy import plot_energy, plot_energy_error

__all__ = ["plot_energy", "plot_energy_error"]
from mslab.plots.stability import plot_oscillator_stability, plot_stability_regions  # noqa: E402

__all__ += ["plot_oscillator_stability", "plot_stability_regions"]
