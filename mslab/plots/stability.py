"""Stability plots: regions in the complex ``z = dt lam`` plane and the oscillator test.

Plotting only: every number comes from :mod:`mslab.stability` (which reads the methods'
own coefficients and update equations).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np

from mslab import stability

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from mslab.integrators.base import Integrator


def plot_stability_regions(methods: Sequence[str | Integrator], ax: Axes | None = None,
                           re: tuple[float, float] = (-4.0, 1.5), im: tuple[float, float] = (-3.5, 3.5),
                           n: int = 301, filled: bool = True) -> Axes:
    """Plot the stability regions ``{z : |R(z)| <= 1}`` of several methods, ``z = dt lam``.

    Parameters
    ----------
    methods : sequence of str or Integrator
    ax : matplotlib Axes, optional
    re, im : (float, float)
        Extent of the plotted part of the plane.
    n : int
        Grid points per axis.
    filled : bool
        Fill each region lightly as well as drawing its boundary ``|R| = 1``.

    Returns
    -------
    ax
    """
    ax = ax if ax is not None else plt.gca()
    xs = np.linspace(re[0], re[1], n)
    ys = np.linspace(im[0], im[1], n)
    colors = _colors(len(methods))
    handles = []
    for k, method in enumerate(methods):
        name = getattr(method, "name", str(method))
        color = colors[k]
        mag = stability.region_grid(method, xs, ys)
        if filled:
            ax.contourf(xs, ys, mag, levels=[0.0, 1.0 + stability.TOL], colors=[color], alpha=0.15)
        ax.contour(xs, ys, mag, levels=[1.0 + stability.TOL], colors=[color], linewidths=1.5)
        handles.append(plt.Line2D([], [], color=color, lw=1.5, label=name))
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.axvline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel(r"Re($h\lambda$)")
    ax.set_ylabel(r"Im($h\lambda$)")
    ax.set_aspect("equal")
    ax.set_title(r"stability regions $|R(h\lambda)| \leq 1$")
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    return ax


def plot_oscillator_stability(methods: Sequence[str | Integrator], ax: Axes | None = None,
                              h_omega_max: float = 4.0, n: int = 400, h_gamma: float = 0.0) -> Axes:
    """Plot the spectral radius of each method's amplification matrix against ``dt w``.

    Above 1 the oscillator's numerical amplitude grows every step.

    Parameters
    ----------
    methods : sequence of str or Integrator
    ax : matplotlib Axes, optional
    h_omega_max : float
    n : int
    h_gamma : float
        ``dt gamma`` (0: undamped).

    Returns
    -------
    ax
    """
    ax = ax if ax is not None else plt.gca()
    w = np.linspace(0.0, h_omega_max, n)
    styles = ("-", "--", ":", "-.")
    for k, (method, color) in enumerate(zip(methods, _colors(len(methods)), strict=True)):
        name = getattr(method, "name", str(method))
        rho = stability.spectral_radius(stability.amplification_matrix(method, w, h_gamma))
        ax.plot(w, rho, lw=1.5, color=color, ls=styles[k % len(styles)], label=name)
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xlabel(r"$h\omega$")
    ax.set_ylabel(r"spectral radius $\rho$ of the one-step map")
    ax.set_ylim(0.0, 2.0)
    ax.set_title(r"oscillator $x'' = -\omega^2 x$" + (f", $h\\gamma$ = {h_gamma:g}" if h_gamma else ""))
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    return ax


def _colors(n: int) -> list:
    """Return n distinguishable colours (tab10, tab20 beyond ten methods)."""
    cmap = plt.get_cmap("tab10" if n <= 10 else "tab20")
    return [cmap(k % cmap.N) for k in range(n)]
