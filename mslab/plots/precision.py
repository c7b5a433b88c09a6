"""Accuracy-versus-cost plots: work-precision, convergence with slope triangles, energy drift.

Plotting only: every number comes from :mod:`mslab.precision` (records, Convergence,
Drift). Each function takes ``ax=None`` and returns the axes; none calls ``plt.show()``.
scipy's solvers are drawn dashed with open markers, mslab's methods solid with filled ones.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from mslab.precision.convergence import Convergence
    from mslab.precision.drift import Drift

_MARKERS = "osD^v<>phH*"
_SCIPY_MARKERS = "xP+1"
_AXIS_LABELS = {
    "wall_time": "wall time [s]",
    "n_force": "force evaluations",
    "n_jac": "Jacobian evaluations",
    "n_solve": "linear solves",
    "steps": "steps",
    "dt": "step dt",
}


def _groups(records: Iterable[dict]) -> dict:
    """Group records as ``{method: [records]}`` in first-seen order."""
    out: dict = {}
    for r in records:
        out.setdefault(r["method"], []).append(r)
    return out


def _usable(rows: Iterable[dict], xkey: str, ykey: str):
    pts = [(r[xkey], r[ykey]) for r in rows
           if r.get("ok", True) and r[xkey] is not None and r[ykey] is not None
           and math.isfinite(r[xkey]) and math.isfinite(r[ykey]) and r[xkey] > 0 and r[ykey] > 0]
    pts.sort()
    return [p[0] for p in pts], [p[1] for p in pts]


def plot_work_precision(records: list[dict], ax: Axes | None = None, x: str = "wall_time",
                        error: str = "error", methods: Sequence[str] | None = None) -> Axes:
    """Plot error against cost for every method: the work-precision diagram (log-log).

    Parameters
    ----------
    records : list of dict
        From :func:`mslab.precision.work_precision` (mslab and scipy records).
    ax : matplotlib Axes, optional
    x : str
        Cost on the horizontal axis: ``"wall_time"`` (default), ``"n_force"``, ``"n_jac"``,
        ``"n_solve"`` or ``"steps"``.
    error : str
        ``"error"`` (final state, max-norm) or ``"error_rms"``.
    methods : sequence of str, optional
        Only these methods (default: all in the records).

    Returns
    -------
    ax
        Lower left is better: less error for less work.
    """
    ax = ax if ax is not None else plt.gca()
    k_mslab = k_scipy = 0
    for name, rows in _groups(records).items():
        if methods is not None and name not in methods:
            continue
        xs, ys = _usable(rows, x, error)
        if not xs:
            continue
        if rows[0].get("solver") == "scipy":
            ax.loglog(xs, ys, ls="--", marker=_SCIPY_MARKERS[k_scipy % len(_SCIPY_MARKERS)], mfc="none",
                      lw=1.2, color=f"0.{2 + 2 * (k_scipy % 4)}", label=name)
            k_scipy += 1
        else:
            ax.loglog(xs, ys, ls="-", marker=_MARKERS[k_mslab % len(_MARKERS)], ms=4, lw=1.5, label=name)
            k_mslab += 1
    ax.set_xlabel(_AXIS_LABELS.get(x, x))
    ax.set_ylabel("error at t_end (max-norm)" if error == "error" else "RMS error over time")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="best", fontsize="small", ncol=2)
    return ax


def _slope_triangle(ax: Axes, x0: float, y0: float, order: float, width: float = 2.0) -> None:
    """Draw a right triangle below a curve: run ``width`` (a factor in dt), rise ``width**order``."""
    x1 = x0 * width
    y1 = y0 * width ** order
    ax.plot([x0, x1, x1, x0], [y0, y0, y1, y0], color="k", lw=0.8)
    ax.annotate(f"{order:g}", (x1, math.sqrt(y0 * y1)), xytext=(3, 0), textcoords="offset points",
                va="center", fontsize="small")


def plot_convergence(result: Convergence | list[dict], ax: Axes | None = None, triangles: bool = True,
                     methods: Sequence[str] | None = None) -> Axes:
    """Plot the error at t_end against dt (log-log), one line per method, with slope triangles.

    Parameters
    ----------
    result : Convergence or list of dict
        From :func:`mslab.precision.convergence` (or its ``records``).
    ax : matplotlib Axes, optional
    triangles : bool
        Draw one slope triangle per expected order (from ``result.expected`` when given,
        else the rounded fitted orders) below the lowest line of that order.
    methods : sequence of str, optional

    Returns
    -------
    ax
    """
    ax = ax if ax is not None else plt.gca()
    records = getattr(result, "records", result)
    fitted = getattr(result, "orders", {}) or {}
    expected = getattr(result, "expected", {}) or {}
    lowest: dict = {}
    for k, (name, rows) in enumerate(_groups(records).items()):
        if methods is not None and name not in methods:
            continue
        xs, ys = _usable(rows, "dt", "error")
        if not xs:
            continue
        p = fitted.get(name)
        label = f"{name} (p = {p:.2f})" if p is not None and math.isfinite(p) else name
        ax.loglog(xs, ys, marker=_MARKERS[k % len(_MARKERS)], ms=4, label=label)
        order = expected.get(name, round(p) if p is not None and math.isfinite(p) else None)
        if order is not None and order > 0:
            x0, y0 = xs[0], ys[0]
            if order not in lowest or y0 < lowest[order][1]:
                lowest[order] = (x0, y0)
    if triangles:
        for order, (x0, y0) in sorted(lowest.items()):
            _slope_triangle(ax, x0, y0 / 4.0, float(order))
    ax.set_xlabel("step dt")
    ax.set_ylabel("error at t_end (max-norm)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="best", fontsize="small", ncol=2)
    return ax


def plot_energy_drift(drifts: Mapping[str, Drift] | Sequence[Drift], ax: Axes | None = None,
                      floor: float = 1e-17) -> Axes:
    """Plot the relative energy error ``|E(t) - E(0)| / E_scale`` over time (log scale) per method.

    Parameters
    ----------
    drifts : dict of Drift or sequence of Drift
        From :func:`mslab.precision.energy_drift`.
    ax : matplotlib Axes, optional
    floor : float
        Values below it (exact zeros at t = 0, round-off) are drawn at ``floor``.

    Returns
    -------
    ax
        Bounded methods stay on a band; drifting ones climb.
    """
    ax = ax if ax is not None else plt.gca()
    items = drifts.values() if isinstance(drifts, dict) else drifts
    for k, d in enumerate(items):
        if d.t.size < 2:
            continue
        style = "-" if d.verdict == "bounded" else "--"
        tag = d.verdict if d.complete else "blew up"
        ax.semilogy(d.t[1:], np.maximum(np.abs(d.error[1:]), floor), ls=style, lw=1.2,
                    color=f"C{k % 10}", label=f"{d.method} ({tag})")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("relative energy error")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="best", fontsize="small", ncol=2)
    return ax
