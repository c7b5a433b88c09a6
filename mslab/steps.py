"""Fixed steps: how many steps of ``dt`` reach ``t_end``, and which of them are saved.

A leaf module (numpy only): the scene settings check a run's ``t_end / dt`` with it, and
the stepping session counts and saves its steps with it.
"""

from __future__ import annotations

import numpy as np

from mslab.checks import real, whole

#: most steps of one run: 2**53, beyond which ``n * dt`` no longer tells two steps apart in float64
MAX_STEPS = float(2**53)


def check_dt(dt: float) -> float:
    """Return ``dt`` as a float: TypeError unless a number (not a bool), ValueError unless finite and > 0."""
    return real("dt", dt, positive=True)


def step_count(t_end: float, dt: float, name: str = "t_end") -> int:
    """Return the number of fixed steps of size dt that reach t_end exactly; ValueError otherwise.

    ``name``: the argument the time was given as (``"t"``: ``advance(t=...)``, whose dt is fixed,
    so the message suggests a time, not a dt).
    """
    dt = check_dt(dt)
    t_end = real(name, t_end, positive=True)
    ratio = t_end / dt
    if not ratio <= MAX_STEPS:  # (also an infinite ratio: a finite t_end over a tiny dt)
        raise ValueError(f"{name} = {t_end:g} is {ratio:.3g} steps of dt = {dt:g}: more than a run can count "
                         f"exactly ({MAX_STEPS:.3g}, where a float64 time stops telling the steps apart)")
    n = max(1, round(ratio))
    if abs(n - ratio) > 1e-9 * max(1.0, ratio):
        given, better, steps = f"{dt:g}", f"{t_end / n:.6g}", f"{ratio:.4g}"
        if given == better or steps == str(n):  # (dt = float32(1e-3) looks like 0.001 at 6 digits)
            given, better, steps = repr(dt), repr(t_end / n), repr(ratio)
        use = f"dt = {better}" if name == "t_end" else f"{name} = {n * dt:.6g}"  # (the session's dt is fixed)
        raise ValueError(f"{name} = {t_end:g} is not a whole number of steps of dt = {given} "
                         f"({steps} steps); use {use} ({n} steps)")
    return n


def steps_to_take(n: object, t: object, dt: float, done: int, end: int | None) -> int:
    """Return the steps of ``advance(n)`` or ``advance(t=...)`` from step ``done`` (``end``: declared).

    ValueError: both or (open-ended) neither given, or a run beyond :data:`MAX_STEPS` steps.
    """
    if n is not None and t is not None:
        raise ValueError("advance takes a number of steps or a time t, not both")
    if t is not None:  # t = 0 is 0 steps, as n = 0 is
        count = 0 if real("t", t, minimum=0.0) == 0.0 else step_count(t, dt, name="t")
    elif n is None:
        if end is None:
            raise ValueError("advance needs a number of steps or a time t (the session has no t_end)")
        count = end - done
    else:
        count = whole("n", n, 0)
    if done + count > MAX_STEPS:
        raise ValueError(f"advance: {count} more steps from step {done} go beyond {MAX_STEPS:.3g} steps, "
                         f"more than a run can count exactly (a float64 time stops telling the steps apart)")
    return count


def save_indices(n_steps: int, save_every: int) -> np.ndarray:
    """Return the saved steps of a run of ``n_steps``: every ``save_every``-th and the last."""
    idx = np.arange(0, n_steps + 1, save_every, dtype=np.int64)
    return idx if idx[-1] == n_steps else np.append(idx, np.int64(n_steps))
