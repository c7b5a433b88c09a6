"""Run settings of a scene (``[run]`` and ``load_scene`` overrides): method, dt, t_end, save_every."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mslab.checks import shown
from mslab.effects.schema import check_keys, integer, number, string
from mslab.errors import SceneError

#: keys of ``[run]`` (also the overrides ``load_scene`` accepts)
RUN_KEYS = ("method", "dt", "t_end", "save_every")
#: most steps a run may take: 1e12 steps at a microsecond each are 12 days
MAX_STEPS = 10**12


def read_run(run: Mapping, dt: float, t_end: float) -> dict:
    """Check a ``[run]`` table; returns the settings it gives (``dt``, ``t_end``: the defaults)."""
    check_keys(run, RUN_KEYS, "run.")
    settings: dict = {}
    if "method" in run:
        settings["method"] = string(run["method"], "run.method")
    if "dt" in run:
        settings["dt"] = number(run["dt"], "run.dt", low=0.0, strict=True)
    if "t_end" in run:
        settings["t_end"] = number(run["t_end"], "run.t_end", low=0.0, strict=True)
    if "save_every" in run:
        settings["save_every"] = integer(run["save_every"], "run.save_every", low=1)
    check_settings(settings, dt=dt, t_end=t_end)
    return settings


def check_settings(settings: Mapping, source: str | None = None, *, dt: float | None = None,
                   t_end: float | None = None, note: str = "") -> None:
    """Check run settings (from the file or overrides).

    The method is known, ``dt`` and ``t_end`` are finite and > 0, ``save_every`` a whole
    number >= 1, and ``t_end / dt`` a whole number of steps (``dt``, ``t_end``: the
    values to use where ``settings`` has none). ``note`` ends every message.
    """
    from mslab.integrators.base import get_method
    from mslab.steps import step_count

    def fail(key: str, reason: str):
        raise SceneError(key, f"{reason}{note}", source)

    if "method" in settings:
        if not isinstance(settings["method"], str):
            fail("run.method", f"must be a string, got {settings['method']!r}")
        try:
            get_method(settings["method"])
        except ValueError as err:
            fail("run.method", str(err))
    for key in ("dt", "t_end"):
        if key in settings:
            value = settings[key]
            number = isinstance(value, int | float) and not isinstance(value, bool)
            if not number or not np.isfinite(float(value) if abs(value) < 1e308 else np.inf) or value <= 0:
                fail(f"run.{key}", f"must be a finite number > 0, got {shown(value)}")
    if "save_every" in settings:
        value = settings["save_every"]
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            fail("run.save_every", f"must be a whole number >= 1, got {value!r}")
    dt = settings.get("dt", dt)
    t_end = settings.get("t_end", t_end)
    if dt is not None and t_end is not None:
        key = "run.dt" if "dt" in settings else "run.t_end"
        steps = float(t_end) / float(dt)
        if steps > MAX_STEPS:
            fail(key, f"dt = {float(dt):.3g} s and t_end = {float(t_end):.3g} s give {steps:.3g} steps, more "
                      f"than {MAX_STEPS:.0e} (days of computing at a microsecond a step): choose "
                      f"dt >= {float(t_end) / MAX_STEPS:.3g} s or a shorter t_end")
        try:
            step_count(float(t_end), float(dt))
        except ValueError as err:
            fail(key, str(err))


def canonical(settings: Mapping) -> dict:
    """Return the settings with the method's registry name (``symplectic-euler`` -> ``symplectic_euler``)."""
    out = dict(settings)
    if "method" in out:
        from mslab.integrators.base import get_method

        out["method"] = get_method(out["method"]).name
    return out
