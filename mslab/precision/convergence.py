"""Convergence: the global error at t_end against dt, and fitted orders."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.base import get_method
from mslab.precision.reference import reference_solution
from mslab.precision.work_precision import work_precision
from mslab.scenes.builder import Scene

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator

#: errors below this are round-off, not truncation error; left out of the order fit
ROUNDOFF_FLOOR = 1e-11


def fit_order(dts: Sequence[float], errors: Sequence[float], floor: float = ROUNDOFF_FLOOR,
              ceiling: float = math.inf) -> float:
    """Least-squares slope of ``log(error)`` against ``log(dt)``.

    Points with a non-finite error, one below ``floor`` (round-off) or one above
    ``ceiling`` (not yet in the asymptotic range) are left out; nan when fewer than two
    points remain.
    """
    dts = np.asarray(dts, dtype=float)
    errors = np.asarray(errors, dtype=float)
    keep = np.isfinite(errors) & (errors > floor) & (errors < ceiling) & (dts > 0)
    if np.count_nonzero(keep) < 2 or np.unique(dts[keep]).size < 2:
        return math.nan
    slope, _ = np.polyfit(np.log(dts[keep]), np.log(errors[keep]), 1)
    return float(slope)


def error_ceiling(scene: Scene, t_end: float) -> float:
    """Return a tenth of the scene's size: larger errors are outside the asymptotic range.

    The size is the larger of the scene's extent (bounding-box diagonal of the initial and
    the reference final positions) and the largest reference speed at ``t_end``.
    """
    ref = reference_solution(scene, t_end)
    x = np.concatenate([scene.state0.x, ref.x_end])
    extent = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))
    return 0.1 * max(extent, float(np.max(np.abs(ref.v_end))), 1e-300)


def fitted_orders(records: list[dict], floor: float = ROUNDOFF_FLOOR, ceiling: float = math.inf) -> dict:
    """Return the :func:`fit_order` of each mslab method in work-precision records.

    Also sets each record's ``local_order`` (the slope from the next larger dt).
    """
    orders = {}
    names = list(dict.fromkeys(r["method"] for r in records if r.get("solver", "mslab") == "mslab"))
    for m in names:
        rows = sorted((r for r in records if r["method"] == m), key=lambda r: -r["dt"])
        prev = None
        for r in rows:
            r["local_order"] = (fit_order([prev["dt"], r["dt"]], [prev["error"], r["error"]], floor, ceiling)
                                if prev is not None else math.nan)
            prev = r
        orders[m] = fit_order([r["dt"] for r in rows], [r["error"] for r in rows], floor, ceiling)
    return orders


@dataclass
class Convergence:
    """Result of :func:`convergence`.

    Attributes
    ----------
    records : list of dict
        ``method``, ``dt``, ``error`` (final-state max-norm), ``error_rms``, ``local_order``
        (slope from the next larger dt), ``n_force``, ``steps``, ``ok``, ``failure``.
    orders : dict
        Fitted order per method: the slope through the records whose error lies between
        ``floor`` and ``ceiling`` only (:func:`fit_order`; by default errors above a tenth of
        the solution's size are left out), so a refit through every record can differ; nan
        when fewer than two usable points remain.
    expected : dict
        ``get_method(m).order`` per method.
    """

    records: list
    orders: dict
    expected: dict

    def as_dict(self) -> dict:
        """Return the records, fitted orders and expected orders as plain data."""
        return {"records": self.records, "orders": self.orders, "expected": self.expected}


def convergence(scene: Scene, methods: Sequence[str | Integrator],
                dts: Sequence[float] | Mapping[str, Sequence[float]], t_end: float | None = None, *,
                floor: float = ROUNDOFF_FLOOR, ceiling: float | None = None, n_save: int = 100,
                jobs: int = 1, progress: bool | None = False, backend: str | None = None) -> Convergence:
    """Global error at ``t_end`` against ``dt`` and the fitted order of each method.

    Parameters
    ----------
    scene : Scene
    methods : sequence of str
    dts : sequence of float, or dict of method name -> sequence of float
        Steps in the asymptotic range (small enough for every method to be stable and
        its leading error term to dominate, large enough to stay above round-off).
    t_end : float, optional
    floor : float
        Errors below it are round-off and left out of the fit.
    ceiling : float, optional
        Errors above it are left out of the fit (default :func:`error_ceiling`, a tenth of
        the solution's size).
    backend : {"auto", "numba", "numpy"}, optional
        Decided once for all the runs (:func:`work_precision`).

    Returns
    -------
    Convergence
        Every run is in ``records``; ``orders`` are fitted through the kept errors only
        (between ``floor`` and ``ceiling``).
    """
    t_end = float(scene.settings.t_end if t_end is None else t_end)
    records = work_precision(scene, methods, dts, t_end, timing=False, n_save=n_save, jobs=jobs,
                             progress=progress, backend=backend)
    ceiling = error_ceiling(scene, t_end) if ceiling is None else ceiling
    orders = fitted_orders(records, floor, ceiling)
    expected = {m: get_method(m).order for m in orders}
    return Convergence(records, orders, expected)
