"""When a run stops: blow-ups of the positions, growth of the energy ledger, the stability pre-check.

No clamps hide an instability (the README's rule). Three checks, each with a scale fixed
from the scene's initial state when the session starts, so a run stepped in any chunks
stops at the same step with the same message:

* **positions**: a non-finite state, or a position beyond ``blowup * (1 + max |x0|)``
  (checked after every step, by the stepping loops themselves);
* **ledger growth** (:class:`LedgerCheck`): the ledger total ``E = K + U + D - W_ext`` is
  constant for the exact motion; an instability whose amplitude saturates (stiff springs
  swinging through zero length, a contact bouncing) keeps the positions bounded but makes
  ``E`` grow. The check reads ``E`` every :attr:`LedgerCheck.every` steps;
* **the pre-check** (:func:`check_stability`): an explicit method's predicted stable dt,
  quoted in every message.
"""

from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING

import numpy as np

from mslab.errors import StabilityWarning

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator
    from mslab.scene import Scene

#: force evaluations between two ledger checks: a check (K and U in numpy, about one numpy
#: force evaluation) then costs a few per cent of the compiled steps between checks
CHECK_EVALS = 128
#: growth that counts as an instability: the ledger gained more than the scene's energy scale
#: (``LEVEL``), and its deviation rose at ``RISE_CHECKS`` checks in a row (or more) by ``GROWTH``
#: times overall; a check whose deviation stays above ``KEEP`` times the rise's peak continues it
LEVEL = 1.0
GROWTH = 100.0
RISE_CHECKS = 4
KEEP = 0.5
#: deviations below this fraction of the scale are round-off: they start no rise
FLOOR = 1e-10


def position_limit(scene: Scene, blowup: float) -> float:
    """Return the largest |position| a run may reach: ``blowup * (1 + max |x0|)``."""
    return blowup * (1.0 + float(np.max(np.abs(scene.state0.x))))


def hint(stable_dt: float | None) -> str:
    """Return the end of a blow-up message: the predicted stable dt, or what to try."""
    if stable_dt is None:
        return "; try a smaller dt or an implicit method"
    if stable_dt == 0:
        return "; no dt is stable for this method on this scene: try an implicit or symplectic method"
    return f"; predicted stable dt = {stable_dt:.4g}"


def check_stability(scene: Scene, integrator: Integrator, dt: float, stable_dt: float | None,
                    stacklevel: int) -> float | None:
    """Return the predicted stable dt (or the given one); warn when dt exceeds it. Counts no work."""
    from mslab.stability import predicted_stable_dt
    from mslab.threads import single_threaded_blas

    predicted = single_threaded_blas(predicted_stable_dt)(scene, integrator)
    if predicted is not None and dt > predicted:
        what = (f"{integrator.name} has no stable dt on this scene: its undamped oscillations grow "
                f"at every dt (slowly when dt is small)"
                if predicted == 0 else f"dt = {dt:g} exceeds the predicted stable dt = {predicted:.4g} "
                f"of {integrator.name} ({dt / predicted:.3g} x)")
        warnings.warn(f"{what}; the run may blow up", StabilityWarning, stacklevel=stacklevel)
    return predicted if stable_dt is None else stable_dt


class LedgerCheck:
    """The saturation detector: growth of the ledger total ``E = K + U + D - W_ext``.

    Checked steps: 1, 2, 4, ... below :attr:`every`, then every :attr:`every` steps, and the
    declared end of a run — step numbers only, so any chunking checks the same steps. At each,
    ``g = (E - E(0)) / scale``. The run is unstable there when ``g`` is NaN or above
    ``energy_blowup`` (default 1e4), or when ``g`` **grew**: ``g > LEVEL`` (the ledger gained
    the scene's whole energy scale, which no method does at a stable dt) after ``|g|`` rose
    over at least ``RISE_CHECKS`` checks in a row (none falling below ``KEEP`` times the
    rise's peak) by ``GROWTH`` times or more. A stable method's error reaches its size and
    stays (symplectic) or drifts slowly; an instability grows geometrically, saturated or
    not, until the positions or the nonlinearity bound it; an impact at a large dt is one
    jump, not a rise, and meets only the ``energy_blowup`` bound. Only gains count:
    implicit methods lose energy.

    ``scale`` is :func:`mslab.ledger.initial_energy_scale`; a scene that starts at rest with
    nothing to release (scale 0: a wind drives it) uses the largest kinetic energy checked
    so far. ``energy_blowup = inf`` turns the check off.
    """

    def __init__(self, scale: float, energy_blowup: float, n_stages: int, end: int | None):
        self.scale, self.energy_blowup, self.end = scale, energy_blowup, end
        self.on = not math.isinf(energy_blowup)
        #: steps between two checks (after the doubling ones)
        self.every = max(1, CHECK_EVALS // max(1, n_stages))
        self._e0 = 0.0
        self._k_max = 0.0
        self._rise = (0, 0.0, 0.0, 0)  # (first step, first |E - E0|, peak |E - E0|, checks)

    def due(self, step: int) -> bool:
        """Return whether the ledger is checked after ``step``."""
        if not self.on:
            return False
        return step % self.every == 0 or step == self.end or (step < self.every and step & (step - 1) == 0)

    def next_due(self, step: int) -> int:
        """Return the first checked step after ``step`` (a large number when the check is off)."""
        if not self.on:
            return 2**62
        nxt = (step // self.every + 1) * self.every
        if step + 1 < self.every:
            nxt = min(nxt, 1 << step.bit_length())
        return min(nxt, self.end) if self.end is not None and self.end > step else nxt

    def start(self, total: float) -> None:
        """Record ``E(0)``."""
        self._e0, self._k_max, self._rise = total, 0.0, (0, 0.0, 0.0, 0)

    def check(self, step: int, total: float, kinetic: float) -> str | None:
        """Record ``E(step)``; return why the run is unstable there, or None."""
        self._k_max = max(self._k_max, kinetic)
        scale = self.scale if self.scale > 0 else self._k_max
        if not scale > 0:
            return None
        change = total - self._e0
        growth = change / scale
        if not growth <= self.energy_blowup:  # NaN counts as over
            return f"grew by {growth:.3g} x the scene's energy scale"
        size = abs(change) if abs(change) > FLOOR * scale else 0.0
        first, low, peak, count = self._rise
        if size > 0 and count and size >= KEEP * peak:
            self._rise = (first, low, max(peak, size), count + 1)
        else:
            self._rise = (step, size, size, 1 if size > 0 else 0)
        first, low, peak, count = self._rise
        if growth > LEVEL and count >= RISE_CHECKS and change >= GROWTH * low:
            return (f"grew by {growth:.3g} x the scene's energy scale, rising over the last {count} "
                    f"checks, {change / low:.3g} x since step {first} (growth only an instability makes: "
                    f"the positions stayed bounded, so its amplitude saturated, e.g. springs swinging "
                    f"through zero length or a contact bouncing)")
        return None
