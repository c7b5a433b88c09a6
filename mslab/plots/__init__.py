"""Plots: ``plot_*(..., ax=None) -> ax``; plotting only, no computation, never ``plt.show()``."""

from mslab.plots.energy import plot_energy, plot_energy_error
from mslab.plots.precision import plot_convergence, plot_energy_drift, plot_work_precision

__all__ = ["plot_energy", "plot_energy_error"]
__all__ += ["plot_convergence", "plot_energy_drift", "plot_work_precision"]
from mslab.plots.stability import plot_oscillator_stability, plot_stability_regions  # noqa: E402

__all__ += ["plot_oscillator_stability", "plot_stability_regions"]
from mslab.plots.scene import animate, plot_configuration  # noqa: E402

__all__ += ["animate", "plot_configuration"]
from mslab.plots.movie import animation_image, animation_png  # noqa: E402

__all__ += ["animation_image", "animation_png"]
