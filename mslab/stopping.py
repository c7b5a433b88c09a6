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
  quoted in every message. The prediction is :mod:`mslab.stability`'s, a layer above this
  one: ``mslab/__init__.py`` hands it down with :func:`set_stable_dt_predictor`.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from mslab.errors import StabilityWarning

if TYPE_CHECKING:
    from mslab.integrators.base import Integrator
    from mslab.scene import Scene

#: force evaluations between two ledger checks. A check of a compiled run sums the springs'
#: energy compiled (``Springs.compiled_energy``: numpy's took 50-100 ms on a 300 x 300 cloth, a
#: sixth of the 128 steps between checks there), the rest (K, gravity) in numpy
CHECK_EVALS = 128
#: an instability, where dt exceeds the stable dt: the ledger's deviation rose ``GROWTH`` times or
#: more over at least ``RISE_CHECKS`` checks in a row (none below ``KEEP`` times the rise's peak) to a
#: gain above ``LEVEL`` times the energy scale, then either stayed within ``PLATEAU`` times that
#: gain for as many steps as the rise took (and ``RISE_CHECKS`` checks), or rose ``GROWTH`` times
#: faster than a linear drift from the rise's start
LEVEL = 1.0
GROWTH = 100.0
RISE_CHECKS = 4
KEEP = 0.5
PLATEAU = 4.0
#: deviations below this fraction of the scale are round-off: they start no rise
FLOOR = 1e-10
#: an impact, where dt exceeds the stable dt: out of calm (not two ``JUMP``-fold gains in a row into
#: the previous check), the ledger gained ``JUMP`` times or more the smaller of its two previous
#: deviations (its base: a check may fall inside a contact), to a new high above ``JUMP_LEVEL``
#: times the energy scale, and kept that gain (within a factor ``1 / KEEP``) at the next check
#: (an instability growing smoothly 10-fold over two intervals grows more than that over one). A
#: penalty contact stepped beyond its limit throws the particle off within one or two steps, too
#: brief for a rise over ``RISE_CHECKS`` checks; an instability already or still growing is left
#: to the rise rules.
JUMP = 10.0
JUMP_LEVEL = 0.1


#: linearisations at a run's state (where the one at its start calls dt stable) a run may make,
#: each at a state ``FARTHER`` times farther from the start (largest |x - x0|) than the one before
RELINEARISE = 8
FARTHER = 1.25

#: ``predict(scene, integrator) -> stable dt or None`` (installed from above; None: no prediction)
_predict: Callable[[Scene, Integrator], float | None] | None = None


def set_stable_dt_predictor(predict: Callable[[Scene, Integrator], float | None] | None) -> None:
    """Install the predicted stable dt of the pre-check (``mslab.stability`` sits above this module)."""
    global _predict
    _predict = predict


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


def predicted(scene: Scene, integrator: Integrator) -> float | None:
    """Return the installed predictor's stable dt (None: no predictor, or no prediction). Counts no work."""
    from mslab.threads import single_threaded_blas

    return None if _predict is None else single_threaded_blas(_predict)(scene, integrator)


def check_stability(scene: Scene, integrator: Integrator, dt: float, stable_dt: float | None,
                    stacklevel: int) -> float | None:
    """Return the predicted stable dt (or the given one); warn when dt exceeds it. Counts no work.

    Without a predictor installed (:func:`set_stable_dt_predictor`) there is nothing to check.
    """
    if _predict is None:
        return stable_dt
    prediction = predicted(scene, integrator)
    if prediction is not None and dt > prediction:
        what = (f"{integrator.name} has no stable dt on this scene: its undamped oscillations grow "
                f"at every dt (slowly when dt is small)"
                if prediction == 0 else f"dt = {dt:g} exceeds the predicted stable dt = {prediction:.4g} "
                f"of {integrator.name} ({dt / prediction:.3g} x)")
        warnings.warn(f"{what}; the run may blow up", StabilityWarning, stacklevel=stacklevel)
    return prediction if stable_dt is None else stable_dt


def beyond_limit(scene: Scene, integrator: Integrator, dt: float,
                 stable_dt: float | None) -> Callable[..., bool | str | None]:
    """Return ``beyond(x=None, v=None)``: whether dt exceeds the stable dt, so that a mode grows.

    ``stable_dt`` (the pre-check's, or the caller's) when given, else the prediction (inf for an
    A-stable implicit method), made on the first call only: a run whose ledger never rises
    never pays for it. None: unknown (no predictor installed, a scene too large to predict).

    Within it, given the run's state ``x, v``, the scene is linearised again there when the
    state lies :data:`FARTHER` times farther from the start than any linearised before (at most
    :data:`RELINEARISE` times a run): a run that strays from its initial state into stiffer
    ones (springs stretched across their anchors stiffen sideways by their tension) can exceed
    the stable dt of the states it reaches while staying within that of its start. Beyond it
    there only, ``beyond`` returns what grows (a str, true) instead of True.
    """
    import dataclasses

    from mslab.state import State

    known: list[bool | None] = []
    again, farthest = [RELINEARISE], [0.0]

    def beyond(x: np.ndarray | None = None, v: np.ndarray | None = None) -> bool | str | None:
        if not known:
            limit = predicted(scene, integrator) if stable_dt is None else stable_dt
            known.append(None if limit is None else dt > limit)
        if known[0] is not False or x is None or v is None or again[0] == 0 or _predict is None:
            return known[0]
        reach = float(np.max(np.abs(x - scene.state0.x)))
        if not reach > FARTHER * farthest[0]:
            return False  # no farther from the start than a state linearised already
        again[0], farthest[0] = again[0] - 1, reach
        there = predicted(dataclasses.replace(scene, state0=State(np.array(x), np.array(v))), integrator)
        if there is None or not dt > there:
            return False
        return (f"a mode unstable at this dt in the state the run reached (linearised there: stable dt "
                f"{there:.4g}, at the start {predicted(scene, integrator):.4g})")

    return beyond


class LedgerCheck:
    """The growth detector: a ledger ``E = K + U + D - W_ext`` that rose as only an instability makes it.

    Checked steps: 1, 2, 4, ... below :attr:`every`, then every :attr:`every` steps, and the
    declared end of a run — step numbers only, so any chunking checks the same steps. At each,
    ``g = (E - E(0)) / scale``. A **rise** is a run of ``RISE_CHECKS`` or more checks in a row,
    none below ``KEEP`` times the largest ``|E - E(0)|`` since its first check (a drop ends it;
    deviations under ``FLOOR * scale`` are round-off and start none; a jump, an impact at a
    large dt, starts one at its top). A rise **qualifies** when it took ``|E - E(0)|`` up
    ``GROWTH`` times or more to a gain ``g > LEVEL`` (the whole energy scale). The run is
    unstable, **where dt exceeds the stable dt** (``beyond``, :func:`beyond_limit`: the
    pre-check's prediction, per mode of the scene linearised at its initial state with every
    contact that may start; 0 where no dt is stable, as for forward Euler undamped), when

    * a qualifying rise then **saturated**: stayed within ``PLATEAU`` times its gain for as
      many steps as it took (and ``RISE_CHECKS`` checks) — the nonlinearity bounded the
      unstable mode's amplitude (stiff springs swinging through zero length, a contact
      bouncing), so the positions never blow up; or
    * a qualifying rise **goes on faster than a linear drift**: ``E - E(0) >= GROWTH * low *
      (s / s0)`` from ``|E - E(0)| = low`` at its first check ``s0`` to the check ``s``. An
      unstable mode's energy grows as ``|R|^(2n)``: from the tiny error of the first steps
      that looks linear at first (forward Euler: ``(1 + h^2 w^2)^n - 1 ~ n h^2 w^2``), then
      outgrows any drift (forward Euler in a wind, its energy x 7.6e3 after 29000 steps,
      under the fixed bound), while a drift (free fall) never qualifies; or
    * an **impact**: out of calm, the ledger jumped ``JUMP`` times or more between two checks
      to a new high above ``JUMP_LEVEL`` times the energy scale and kept it at the next check
      (:data:`JUMP`). A penalty contact stepped just beyond its limit (1.1 x, lesson 08)
      throws the particle off within a step or two, its energy x 12: too brief for a rise, and
      a single contact (no successive ones to compare). Its gain per contact alone tells
      nothing: within the limit a contact's gain is the method's error, up to x 9 at 0.99 x
      (kinked by the contact switching on mid-step), unbounded as dt nears the limit; beyond
      it the contact's mode is unstable, so the gain is the instability's.

    **Within the stable dt** the ledger gives no verdict: every mode's step matrix then has
    its eigenvalues in the unit disc, so its amplitude stays bounded — but by the conditioning
    of that matrix, which diverges at the edge of the stability region: just below the limit
    a stable mode's energy swings a thousand-fold or more (x 1.3e4 for symplectic Euler at
    0.995 x its limit on the oscillator, bounded over 1e5 steps), rising within a few dozen
    steps as fast as a saturating instability does, and a free fall or a driven scene's
    ledger drifts linearly (``m g^2 h t / 2`` under forward Euler): the method's known error,
    which no threshold on the energy alone tells from an instability. Such runs stop on their
    positions only. Where the stable dt is unknown (no prediction) the rises and the bound
    count as beyond it.

    A growth the checks do not resolve (from round-off to beyond the bounds between two
    checks) is left to the positions and to :meth:`over`, the bound ``energy_blowup``
    (default 1e4) on the saved samples' ledger, also read only beyond the stable dt. Only
    gains count.

    **Groups** (:func:`mslab.ledger.energy_groups`): particles no effect couples exchange no
    energy, so each group's ledger ``K + U - W_ext`` (the others held at ``x0``) is judged so
    against the group's own scale (:func:`mslab.ledger.group_scales`): a resting particle
    bouncing away on its contact is seen even where a heavy fast body elsewhere makes the
    scene's energy scale large. One group: the whole ledger against ``scale``.

    ``scale`` is :func:`mslab.ledger.initial_energy_scale`; a scene that starts at rest with
    nothing to release (scale 0: a wind drives it) uses the largest kinetic energy checked
    so far. ``energy_blowup = inf`` turns the check off. The rule keeps O(1) state per group
    and the stable dt is predicted once, at the first rise that would stop the run: the cost per step is
    that of the checks.
    """

    def __init__(self, scale: float, energy_blowup: float, n_stages: int, end: int | None,
                 scene: Scene | None = None, beyond: Callable[[], bool | None] | None = None):
        from mslab.ledger import energy_groups, group_ledgers, group_scales

        self.scale, self.energy_blowup, self.end = scale, energy_blowup, end
        self.on = not math.isinf(energy_blowup)
        self._beyond = beyond if beyond is not None else lambda x=None, v=None: None
        #: steps between two checks (after the doubling ones)
        self.every = max(1, CHECK_EVALS // max(1, n_stages))
        self._groups = energy_groups(scene) if scene is not None and self.on else None
        if self._groups is not None:
            self._system, self._x0, self._ledgers = scene.system, scene.state0.x, group_ledgers
            self._scales = group_scales(scene, self._groups)
            self._g0 = group_ledgers(self._system, self._groups, self._x0, scene.state0.v, self._x0)
        self.start(0.0)

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
        self._e0, self._k_max = total, 0.0
        self._watch = [_Growth() for _ in range(1 if self._groups is None else self._scales.size)]

    def check(self, step: int, total: float, kinetic: float, x: np.ndarray | None = None,
              v: np.ndarray | None = None) -> str | None:
        """Record ``E(step)`` (groups: their ledgers at ``x, v``); return why the run is unstable, or None."""
        self._k_max = max(self._k_max, kinetic)
        fallback = self.scale if self.scale > 0 else self._k_max
        beyond = functools.partial(self._beyond, x, v)  # linearised at this state, where within at the start
        if self._groups is None or x is None:
            return self._watch[0].update(step, total - self._e0, fallback, "the scene's", beyond)
        changes = self._ledgers(self._system, self._groups, x, v, self._x0) - self._g0
        for g, (watch, change) in enumerate(zip(self._watch, changes, strict=True)):
            scale = self._scales[g] if self._scales[g] > 0 else fallback
            who = (f"the energy scale of particles {np.flatnonzero(self._groups == g)[:5].tolist()} (a group "
                   f"no effect couples to the rest: no energy flows in or out); its")
            reason = watch.update(step, float(change), scale, who, beyond)
            if reason is not None:
                return reason
        return None

    def over(self, total: np.ndarray, first: int, scale: float) -> int | None:
        """Return the first saved sample from ``first`` whose ledger gained over ``energy_blowup * scale``.

        ``total``: the ledger totals of the samples so far (NaN counts as over).
        """
        if not self.on:
            return None
        growth = (total[first:] - total[0]) / scale
        if np.all(growth <= self.energy_blowup) or self._beyond() is False:
            return None
        bad = np.flatnonzero(~(growth <= self.energy_blowup))
        return first + int(bad[0]) if bad.size else None


class _Growth:
    """The rise rules of :class:`LedgerCheck` for one ledger (the scene's, or a group's)."""

    def __init__(self):
        self._rise = (0, 0.0, 0.0, 0)  # (first step, first |E - E0|, peak |E - E0|, checks)
        self._risen: tuple | None = None  # (step, E - E0, rise's first step and |E - E0|, checks since)
        #: (previous check's step, |E - E0| there and at the two checks before it): none before the
        #: first checks (a jump is measured from checks, not from the start)
        self._last = (0, math.inf, math.inf, math.inf)
        self._jump: tuple | None = None  # (step, E - E0, previous check's step, base): a jump to be kept

    def update(self, step: int, change: float, scale: float, who: str,
               beyond_limit: Callable[[], bool | str | None]) -> str | None:
        """Record the ledger's change ``E - E(0)`` at ``step``; return why the run is unstable, or None."""
        if not scale > 0:
            return None
        growth = change / scale
        size = abs(change) if abs(change) > FLOOR * scale else 0.0
        first, low, peak, count = self._rise
        if size > 0 and count and size >= KEEP * peak:
            self._rise = (first, low, max(peak, size), count + 1)
        else:
            self._rise = (step, size, size, 1 if size > 0 else 0)
        first, low, peak, count = self._rise
        rose = growth > LEVEL and count >= RISE_CHECKS and change >= GROWTH * low
        risen, reason = self._risen, None
        if risen is not None and size <= PLATEAU * risen[1]:
            at, level, since, start, n = self._risen = (*risen[:4], risen[4] + 1)
            if step - at >= at - since and n >= RISE_CHECKS:
                reason = (f"grew by {level / scale:.3g} x {who} energy scale by step {at}, rising "
                          f"{level / start:.3g} x since step {since}, and stayed there up to step {step} "
                          f"(now {growth:.3g} x): {{why}} whose amplitude saturated, so the positions "
                          f"stayed bounded (e.g. stiff springs swinging through zero length, a contact "
                          f"bouncing)")
        elif rose:
            self._risen = (step, change, first, low, 0)  # risen; a plateau, or more growth, must follow
        else:
            self._risen = None
        if reason is None and rose and change >= GROWTH * low * (step / first):
            reason = (f"rose {change / low:.3g} x in {count} checks from step {first} to {growth:.3g} x "
                      f"{who} energy scale at step {step}, {change / (low * step / first):.3g} x more than "
                      f"a linear drift: the geometric growth of {{why}}, stopped before its amplitude "
                      f"saturated or the positions blew up")
        jump = self._impact(step, change, size, scale)
        if reason is None and jump is not None:
            at, level, before, base = jump
            reason = (f"gained {level / scale:.3g} x {who} energy scale between steps {before} and {at} "
                      f"({level / base:.3g} x its deviation before) and kept it up to step {step} (now "
                      f"{growth:.3g} x): an impact that gained energy within a few steps through {{why}} "
                      f"(e.g. a penalty contact stepped beyond its stable dt, throwing the particle off)")
        if reason is None:
            return None
        beyond = beyond_limit()  # predicted at the first rise that would stop the run (again at its state)
        if beyond is False:
            return None  # a stable mode's transient near the limit, or a drift: the method's error
        if isinstance(beyond, str):
            return reason.format(why=beyond)
        return reason.format(why="a mode unstable at this dt" if beyond else
                             "an instability (no stable dt is known here)")

    def _impact(self, step: int, change: float, size: float, scale: float) -> tuple | None:
        """Record a check for the impact rule; return the jump the ledger kept up to ``step``, or None."""
        before, last, earlier, earliest = self._last
        base = max(min(last, earlier), FLOOR * scale)  # the smaller: a check may fall inside a contact
        floor = FLOOR * scale
        growing = earlier >= JUMP * max(earliest, floor) and last >= JUMP * max(earlier, floor)
        pending, self._last = self._jump, (step, size, last, earlier)
        kept = pending is not None and KEEP * pending[1] <= change <= pending[1] / KEEP
        jumped = not growing and change > max(JUMP_LEVEL * scale, last) and change >= JUMP * base
        self._jump = (step, change, before, base) if jumped else None
        return pending if kept else None
