"""Fixed steps: how many steps of ``dt`` reach ``t_end``, and which of them are saved.

A leaf module (numpy only): the scene settings check a run's ``t_end / dt`` with it, and
the stepping session counts and saves its steps with it.
"""

from __future__ import annotations

import numpy as np

from mslab.checks import real

#: most steps of one run: 2**53, beyond which ``n * dt`` no longer tells two steps apart in float64
MAX_STEPS = float(2**53)


def check_dt(dt: float) -> float:
    """Return ``dt`` as a float: TypeError unless a number (not a bool), ValueError unless finite and > 0."""
    return real("dt", dt, positive=True)


def step_count(t_end: float, dt: float) -> int:
    """Return the number of fixed steps of size dt that reach t_end exactly; ValueError otherwise."""
    dt = check_dt(dt)
    t_end = real("t_end", t_end, positive=True)
    ratio = t_end / dt
    if not ratio <= MAX_STEPS:  # (also an infinite ratio: a finite t_end over a tiny dt)
        raise ValueError(f"t_end = {t_end:g} is {ratio:.3g} steps of dt = {dt:g}: more than a run can count "
                         f"exactly ({MAX_STEPS:.3g}, where a float64 time stops telling the steps apart)")
    n = max(1, round(ratio))
    if abs(n - ratio) > 1e-9 * max(1.0, ratio):
        raise ValueError(f"t_end = {t_end:g} is not a whole number of steps of dt = {dt:g} "
                         f"({ratio:.4g} steps); use dt = {t_end / n:.6g} ({n} steps)")
    return n


def save_indices(n_steps: int, save_every: int) -> np.ndarray:
    """Return the saved steps of a run of ``n_steps``: every ``save_every``-th and the last."""
    idx = np.arange(0, n_steps + 1, save_every, dtype=np.int64)
    return idx if idx[-1] == n_steps else np.append(idx, np.int64(n_steps))
