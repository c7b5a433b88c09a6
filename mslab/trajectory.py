"""What a run returns: saved samples, the energy ledger and the counted work."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from mslab.system import Counters


@dataclass
class Energy:
    """Energy ledger over the saved times, each an array of shape (n_saved,).

    Attributes
    ----------
    kinetic : ndarray
        ``K = sum_i m_i |v_i|^2 / 2``.
    potential : ndarray
        ``U``: the potential energies of the conservative effects.
    dissipated : ndarray
        ``D``: work removed so far by dissipative effects (drag, spring damping, friction),
        ``>= 0`` and non-decreasing.
    external : ndarray
        ``W_ext``: work done *on* the system so far by external drives (a wind), positive
        when the drive puts energy in. Zeros when no effect drives (the default, so
        ``Energy(K, U, D)`` still holds every older ledger).

    The balance is ``K + U + D = E(0) + W_ext``: :attr:`total` ``= K + U + D - W_ext`` is
    constant for the exact motion, damped, driven or neither.
    """

    kinetic: np.ndarray
    potential: np.ndarray
    dissipated: np.ndarray
    external: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.external is None:
            self.external = np.zeros(np.shape(self.kinetic))

    def __repr__(self) -> str:
        """Return a one-line summary (samples, first and last total), never the arrays."""
        n = len(self.kinetic)
        ends = f"; total {self.total[0]:.6g} .. {self.total[-1]:.6g}" if n else ""
        return f"Energy({n} samples of K, U, D, W_ext{ends})"

    @property
    def total(self) -> np.ndarray:
        """``K + U + D - W_ext``: constant for the exact solution, damped, driven or not."""
        return self.kinetic + self.potential + self.dissipated - self.external

    def energy_scale(self) -> float:
        """Return the run's energy scale: the largest kinetic energy in the first quarter of the run.

        Unlike ``|E(0)|`` it does not depend on where potential energy is zero (a chain
        starting at height 0 has E(0) = 0), and unlike the whole run's maximum a late
        blow-up does not shrink the relative error. Falls back to ``|E(0)|``, then 1.
        """
        k = self.kinetic[: max(1, len(self.kinetic) // 4)]
        for scale in (float(np.max(k)), abs(float(self.total[0]))):
            if scale > 0.0 and np.isfinite(scale):
                return scale
        return 1.0

    def relative_drift(self) -> np.ndarray:
        """``(E(t) - E(0)) / energy_scale()`` for the ledger total ``E = K + U + D - W_ext``."""
        total = self.total
        return (total - total[0]) / self.energy_scale()


@dataclass
class Stats(Counters):
    """Work and time of a run: the System's counters during stepping, steps and wall time.

    The work counters are the fields of :class:`~mslab.system.Counters` (one list for both).
    """

    method: str = ""
    dt: float = 0.0
    steps: int = 0
    wall_time: float = 0.0

    def as_dict(self) -> dict:
        """Return the method, dt, steps, every counter and the wall time, as a plain dict."""
        counters = {f.name: getattr(self, f.name) for f in fields(Counters)}
        return {"method": self.method, "dt": self.dt, "steps": self.steps, **counters,
                "wall_time": self.wall_time}


@dataclass
class Trajectory:
    """Saved samples of a run.

    Attributes
    ----------
    t : ndarray, shape (n_saved,)
    x, v : ndarray, shape (n_saved, n_particles, dim)
    energy : Energy
    stats : Stats
    complete : bool
        False for the part of a run kept when it blew up or was interrupted.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    energy: Energy
    stats: Stats
    complete: bool = True
    scene_name: str = ""

    def __repr__(self) -> str:
        """Return a one-line summary (scene, samples, time span, method, steps), never the arrays."""
        n, span = len(self.t), (f"t {self.t[0]:g}..{self.t[-1]:g}" if len(self.t) else "no time")
        shape = "x".join(str(d) for d in np.shape(self.x)[1:])
        state = "complete" if self.complete else "partial"
        return (f"Trajectory({self.scene_name!r}: {n} samples of {shape}, {span}, {self.stats.method} "
                f"dt={self.stats.dt:g}, {self.stats.steps} steps, {state})")
