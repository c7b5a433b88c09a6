"""Fixed-step simulation in one call: a stepping session advanced to its end.

Decisions (documented in the README):

* **Fixed steps, t_end reached exactly.** ``t_end / dt`` must be a whole number (to a
  relative 1e-9); otherwise ``simulate`` refuses and names the nearest valid dt
  (:func:`mslab.steps.step_count`). A shortened last step would break the multistep
  methods (Verlet, leapfrog).
* **Bounded memory.** Only every ``save_every``-th state (and the last) is kept.
* **Energy ledger** at the saved times (:mod:`mslab.ledger`): kinetic K, potential U,
  dissipated work D (integrated by the method itself), external work W_ext put in by drives
  such as a wind, total ``K + U + D - W_ext`` (constant for exact dynamics).
* **Counted work.** ``stats`` reports what the System counted during stepping only.
* **No hidden clamps** (:mod:`mslab.stopping`): a non-finite state, positions beyond
  ``blowup`` times the scene's size, or a ledger that grows the way only an instability
  makes it grow stop the run with :class:`~mslab.errors.InstabilityError`.
* **One code path.** ``simulate`` is ``Simulation(...).advance()`` (:mod:`mslab.simulation`):
  a run stepped frame by frame through a session is bitwise the same run.
"""

from __future__ import annotations

import time
import warnings
import weakref

from mslab.checks import shown
from mslab.integrators.base import Integrator
from mslab.ledger import initial_energy_scale, xs_bytes
from mslab.progress import check_progress
from mslab.scene import Scene
from mslab.simulation import Simulation, SimulationInterrupted
from mslab.steps import step_count
from mslab.trajectory import Trajectory


def simulate(scene: Scene, method: str | Integrator | None = None, dt: float | None = None,
             t_end: float | None = None, save_every: int | None = None, *,
             progress: bool | None = None, blowup: float = 1e6,
             stable_dt: float | None = None, backend: str | None = None,
             check_stability: bool = True, energy_blowup: float = 1e4,
             threads: int | None = None, dtype: str = "float64") -> Trajectory:
    """Integrate a scene with a fixed step: ``Simulation(...)`` advanced to ``t_end``.

    Parameters
    ----------
    scene : Scene
    method : str or Integrator, optional
        Registry name (see ``mslab.methods()``); default ``scene.settings.method``.
    dt, t_end : float, optional
        Step and end time (``t_end/dt`` a whole number); defaults from the scene.
    save_every : int, optional
        Keep every n-th state (and always the last one).
    progress : bool, None or object with ``update(n)``
        Progress by the clock (:class:`mslab.progress.Progress`): None shows it on a
        terminal once the run has taken about 2 s, True always, False never; an object
        (a sweep's shared bar) receives ``update(n_steps_done)`` and is not closed here.
    blowup : float
        A position beyond ``blowup * (1 + scene size)`` counts as a blow-up.
    energy_blowup : float
        The ledger check (:class:`mslab.stopping.LedgerCheck`): where dt exceeds the stable dt
        (predicted per mode), a ledger ``K + U + D - W_ext`` above this many times the scene's
        energy scale (:func:`initial_energy_scale`, from the initial state), or one that *grew*
        past that scale geometrically or jumped there in an impact — an instability, saturated
        with bounded positions or not — stops the run at the checked step where it is found (the
        error's step and time, ``stats`` and the kept samples all describe that stopping point).
        Within the stable dt the ledger gives no verdict (a stable mode's energy swings far near
        the limit; a drive makes it drift) unless the scene, linearised again at the run's
        state, is beyond its limit there. ``inf`` turns the check off.
    stable_dt : float, optional
        Predicted stable step, quoted in the InstabilityError message; the ledger check reads
        a run with a larger dt as beyond the stable dt (default: the prediction).
    backend : {"auto", "numba", "numpy"}, optional
        Stepping loop, fixed for the run (:mod:`mslab.fast`); None reads ``$MSLAB_BACKEND``
        (default ``"auto"``: compiled where it applies and the run repays loading it).
    check_stability : bool
        For explicit methods, predict the largest stable dt first
        (:func:`mslab.stability.predicted_stable_dt`; not counted in ``stats``) and warn with
        :class:`~mslab.errors.StabilityWarning` when dt exceeds it; the run goes on, and a
        blow-up then quotes the prediction. Skipped above 5000 degrees of freedom.
    threads : int, optional
        Threads of the compiled loops (:func:`mslab.jit.thread_count`); None reads
        ``$MSLAB_THREADS``, else every core. The result is bitwise the same for any count.
    dtype : {"float64", "float32"}
        Precision of the stepping loop. ``"float32"`` steps the compiled loop only (ValueError
        with ``backend="numpy"``, an implicit method or an effect without a compiled kernel):
        about half the memory traffic, errors of float32 round-off growing with the steps
        (measured in docs/precision.md, "float32"); saved samples and the ledger stay float64.

    Returns
    -------
    Trajectory

    Raises
    ------
    InstabilityError
        The state became non-finite or blew up (``.trajectory`` keeps the saved part).
    ConvergenceError
        An implicit method's iteration failed.
    SimulationInterrupted
        Ctrl-C (``.trajectory`` keeps the saved part).
    """
    if not isinstance(scene, Scene):  # before reading its settings
        hint = f" (a scene name: mslab.load_scene({scene!r}))" if isinstance(scene, str) else ""
        raise TypeError(f"scene must be an mslab Scene{hint}, got {type(scene).__name__} {shown(scene)}")
    check_progress(progress)  # cheap checks before the session's set-up
    s = scene.settings
    begun = time.perf_counter()
    sim = Simulation(scene, method, dt, t_end=s.t_end if t_end is None else t_end, save_every=save_every,
                     blowup=blowup, stable_dt=stable_dt, backend=backend, check_stability=check_stability,
                     energy_blowup=energy_blowup, threads=threads, dtype=dtype, _stacklevel=3)
    sim.advance(progress=progress)
    _frame_loop_hint(scene, sim, time.perf_counter() - begun)
    return sim._trajectory(sim._samples.k, True, current=True, handover=True)  # the session is dropped


#: a call of at most this many steps is a "short" one; this many alike in a row on one system warn once
SHORT_CALL, SHORT_CALLS = 256, 10
_short: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # System: (alike, calls, seconds, ...)


def _frame_loop_hint(scene: Scene, sim: Simulation, seconds: float) -> None:
    """Warn once, after :data:`SHORT_CALLS` alike short calls on one system: a frame loop needs a session.

    A frame loop through ``simulate`` (each frame a new scene from the last state, the same
    system) redoes the set-up a session does once (copy, stability pre-check, backend,
    energy scale); the warning names the measured factor: the calls' whole time over their
    stepping time. Counted by calls alike (same method, dt and steps: a sweep over dt never
    warns), never by timing, so whether it warns is deterministic.
    """
    alike = (sim.integrator.name, sim.dt, sim.step)
    if sim.step > SHORT_CALL:
        _short.pop(scene.system, None)
        return
    last, calls, total, stepping, warned = _short.get(scene.system, (None, 0, 0.0, 0.0, False))
    if last != alike:
        calls, total, stepping = 0, 0.0, 0.0
    calls, total, stepping = calls + 1, total + seconds, stepping + sim.stats.wall_time
    _short[scene.system] = (alike, calls, total, stepping, warned or calls >= SHORT_CALLS)
    if calls == SHORT_CALLS and not warned:
        warnings.warn(f"simulate was called {calls} times on scene {scene.name!r} for {sim.step} steps "
                      f"each; each call costs {total / max(stepping, 1e-9):.3g}x its stepping time (set-up "
                      f"redone every call): a frame loop belongs in mslab.Simulation(scene, ...).advance(n)",
                      FrameLoopWarning, stacklevel=3)


class FrameLoopWarning(UserWarning):
    """``simulate`` called again and again for a few steps on one scene: use :class:`Simulation`."""


__all__ = ["FrameLoopWarning", "Simulation", "SimulationInterrupted", "initial_energy_scale", "simulate",
           "step_count", "xs_bytes"]
