"""What a run will cost, said before it starts: steps, saved samples, memory, time.

``run_cost`` counts the steps and the saved samples of a run and the bytes its saved data
take (positions and velocities, ``2 x n_saved x n_particles x dim`` floats, plus five
scalars per sample: time, dissipated work, kinetic and potential energy, ledger total).
``check_memory`` refuses a run whose saved data exceed a budget, by default
:data:`DEFAULT_FRACTION` of the machine's available memory, in one line that names the
``save_every`` and the ``t_end`` that would fit. ``time_per_step`` measures a few steps
(after one untimed step, so compilation stays out) for an estimate of the whole run.
"""

from __future__ import annotations

import math
import os
import re
import time
import warnings
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator
    from mslab.scenes.builder import Scene

#: share of the available memory a run's saved data may take by default
DEFAULT_FRACTION = 0.5
#: floats kept per saved sample besides x and v: t, dissipated, kinetic, potential, total
SCALARS_PER_SAMPLE = 5

_UNITS = {"": 1, "b": 1, "k": 2**10, "kb": 10**3, "kib": 2**10, "m": 2**20, "mb": 10**6, "mib": 2**20,
          "g": 2**30, "gb": 10**9, "gib": 2**30, "t": 2**40, "tb": 10**12, "tib": 2**40}


def parse_size(text: str) -> int:
    """Bytes from ``"2G"``, ``"512M"``, ``"1.5GiB"``, ``"800MB"`` or a plain number of bytes.

    Raises ValueError (one line naming the valid forms) for anything else.
    """
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([A-Za-z]*)\s*", str(text))
    unit = match.group(2).lower() if match else None
    size = float(match.group(1)) * _UNITS[unit] if match and unit in _UNITS else float("nan")
    if not (0 < size < float("inf")):  # 1e999 is inf, not a size
        raise ValueError(f"not a memory size: '{text}'; write e.g. 2G, 512M, 1.5GiB or a number of bytes")
    return int(size)


def size_text(n_bytes: float) -> str:
    """``"48 kB"``, ``"1.2 GB"``... (powers of 1024, written kB, MB, GB, TB)."""
    value = float(n_bytes)
    for unit in ("B", "kB", "MB", "GB"):
        if value < 1024:
            return f"{value:.3g} {unit}"
        value /= 1024
    return f"{value:.3g} TB"


def count_text(n: int) -> str:
    """Write a count as people read it: ``"4000"``, and ``"4e+300"`` rather than 301 digits."""
    digits = str(abs(int(n)))
    if len(digits) <= 9:
        return str(int(n))
    sign = "-" if n < 0 else ""
    return f"{sign}{digits[0]}.{digits[1:3]}e+{len(digits) - 1}".replace(".00e", "e")


def available_memory() -> int | None:
    """Bytes of memory available to a new computation (``MemAvailable``), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def default_budget() -> int | None:
    """:data:`DEFAULT_FRACTION` of the available memory (None when it is unknown)."""
    free = available_memory()
    return None if free is None else int(DEFAULT_FRACTION * free)


@dataclass
class RunCost:
    """Size of a fixed-step run, known before it starts.

    Attributes
    ----------
    steps, n_saved, save_every : int
    t_end, dt : float
    n_particles, dim : int
    bytes_saved : int
        Bytes of the saved data (x, v and the per-sample scalars).
    """

    steps: int
    n_saved: int
    save_every: int
    t_end: float
    dt: float
    n_particles: int
    dim: int
    bytes_saved: int

    @property
    def bytes_per_sample(self) -> int:
        """Bytes of one saved sample: positions, velocities and the per-sample scalars."""
        return 8 * (2 * self.n_particles * self.dim + SCALARS_PER_SAMPLE)

    def describe(self) -> str:
        """``"2000 steps, 201 saved samples (save_every 10): 48 kB of saved data"``."""
        return (f"{count_text(self.steps)} steps, {count_text(self.n_saved)} saved samples (save_every "
                f"{count_text(self.save_every)}): {size_text(self.bytes_saved)} of saved data")

    def as_dict(self) -> dict:
        """Return the cost as plain data (for JSON)."""
        return asdict(self)


def run_cost(scene: Scene, dt: float | None = None, t_end: float | None = None,
             save_every: int | None = None) -> RunCost:
    """Return the steps, saved samples and bytes of saved data of a run.

    ``dt``, ``t_end`` and ``save_every`` default to ``scene.settings``.
    """
    from mslab.simulate import step_count

    s = scene.settings
    dt = float(s.dt if dt is None else dt)
    t_end = float(s.t_end if t_end is None else t_end)
    save_every = int(s.save_every if save_every is None else save_every)
    steps = step_count(t_end, dt)
    n_saved = steps // save_every + 1 + (1 if steps % save_every else 0)
    n, dim = scene.state0.x.shape
    cost = RunCost(steps, n_saved, save_every, t_end, dt, n, dim, 0)
    cost.bytes_saved = n_saved * cost.bytes_per_sample
    return cost


def memory_problem(cost: RunCost, budget: int | None, budget_name: str = "") -> str | None:
    """One line saying why ``cost`` does not fit in ``budget`` bytes (None: it fits).

    Names the smallest ``save_every`` and the longest ``t_end`` (a whole number of steps)
    that fit, or says that even two samples do not fit.
    """
    if budget is None or cost.bytes_saved <= budget:
        return None
    per = cost.bytes_per_sample
    fits = budget // per  # samples that fit
    what = (f"the saved data would need {size_text(cost.bytes_saved)} ({count_text(cost.n_saved)} samples of "
            f"{count_text(cost.n_particles)} particles), over the memory budget of {size_text(budget)}"
            f"{f' ({budget_name})' if budget_name else ''}")
    if fits < 2:
        return f"{what}; even two samples do not fit: raise --max-memory or use a smaller scene"
    every = math.ceil(cost.steps / (fits - 2)) if fits > 2 else cost.steps
    longest = (fits - 1) * cost.save_every * cost.dt
    return (f"{what}; use save_every >= {count_text(every)} or t_end <= {longest:.6g} "
            f"(or raise --max-memory)")


def time_per_step(scene: Scene, method: str | Integrator | None = None, dt: float | None = None, *,
                  seconds: float = 0.3, max_steps: int = 100_000) -> tuple[float, int]:
    """Measure the seconds per step on the first steps of a run; return it and how many steps were timed.

    One untimed step first (it pays compilation and first-call costs), then runs of 1, 2,
    4, ... steps until one takes ``seconds / 2`` (or ``max_steps``); the time per step is the
    slope between the one-step run and the last one, so the fixed cost of starting a run
    stays out. A scene of slow steps costs about three of them. Warnings and blow-ups of
    these few steps are ignored: they are the run's business.
    """
    from mslab.errors import InstabilityError, StabilityWarning
    from mslab.integrators.base import get_method
    from mslab.simulate import simulate

    dt = float(scene.settings.dt if dt is None else dt)
    method = get_method(scene.settings.method if method is None else method)

    def timed(n: int) -> float:
        start = time.perf_counter()
        simulate(scene, method, dt, n * dt, n, progress=False, check_stability=False)
        return time.perf_counter() - start

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StabilityWarning)
        try:
            timed(1)
            one = last = timed(1)
            n = 1
            while last < seconds / 2 and 2 * n <= max_steps:
                n *= 2
                last = timed(n)
        except InstabilityError:
            return math.nan, 0
    slope = (last - one) / (n - 1) if n > 1 else one
    return (slope if slope > 0 else last / n), n
