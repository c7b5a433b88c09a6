"""Fixed-step simulation: run an integrator on a scene, keep saved samples, count the work.

Decisions (documented in the README):

* **Fixed steps, t_end reached exactly.** ``t_end / dt`` must be a whole number (to a
  relative 1e-9); otherwise ``simulate`` refuses and names the nearest valid dt. A
  shortened last step would break the multistep methods (Verlet, leapfrog).
* **Bounded memory.** Only every ``save_every``-th state (and the last) is kept.
* **Energy ledger** at the saved times: kinetic K, potential U, dissipated work D
  (integrated by the method itself), external work W_ext put in by drives such as a wind
  (from the saved positions: the drive is a constant force), total ``K + U + D - W_ext``
  (constant for exact dynamics).
* **Counted work.** ``stats`` reports what the System counted during stepping only.
* **No hidden clamps.** A non-finite state, or positions beyond ``blowup`` times the
  scene's size, stops the run with :class:`~mslab.errors.InstabilityError`.
* **Backends.** ``backend="auto"`` (default, see :mod:`mslab.fast`) runs the steps of an
  explicit Runge-Kutta or splitting method (Verlet, leapfrog too) in a compiled loop when
  every effect of the scene has a kernel and the run is long enough to repay loading the
  compiled code; ``"numpy"`` always runs the readable loop below. Both give the same
  samples (to 1e-12), counters, energy ledger (the effects' own energies) and errors.
"""

from __future__ import annotations

import time
import warnings
from typing import TYPE_CHECKING

import numpy as np

from mslab import fast
from mslab.effects.gravity import Gravity
from mslab.errors import ConvergenceError, InstabilityError, StabilityWarning, StepFailure
from mslab.integrators.base import Integrator, get_method
from mslab.scenes.builder import Scene
from mslab.threads import single_threaded_blas
from mslab.trajectory import Energy, Stats, Trajectory

if TYPE_CHECKING:
    from mslab.system import System


class SimulationInterrupted(KeyboardInterrupt):
    """Ctrl-C during ``simulate``: ``.trajectory`` holds what was computed."""

    def __init__(self, trajectory: Trajectory):
        super().__init__("interrupted")
        self.trajectory = trajectory


def step_count(t_end: float, dt: float) -> int:
    """Return the number of fixed steps of size dt that reach t_end exactly; ValueError otherwise."""
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
    if not (np.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be a finite number > 0, got {t_end!r}")
    ratio = t_end / dt
    n = max(1, round(ratio))
    if abs(n - ratio) > 1e-9 * max(1.0, ratio):
        raise ValueError(f"t_end = {t_end:g} is not a whole number of steps of dt = {dt:g} "
                         f"({ratio:.4g} steps); use dt = {t_end / n:.6g} ({n} steps)")
    return n


def _save_indices(n_steps: int, save_every: int) -> np.ndarray:
    idx = np.arange(0, n_steps + 1, save_every)
    return idx if idx[-1] == n_steps else np.append(idx, n_steps)


@single_threaded_blas
def simulate(scene: Scene, method: str | Integrator | None = None, dt: float | None = None,
             t_end: float | None = None, save_every: int | None = None, *,
             progress: bool | None = None, blowup: float = 1e6,
             stable_dt: float | None = None, backend: str | None = None,
             check_stability: bool = True, energy_blowup: float = 1e4) -> Trajectory:
    """Integrate a scene with a fixed step.

    Runs with single-threaded BLAS (:mod:`mslab.threads`): Newton's solves and the
    step-limit prediction work on small matrices, where threads only cost time.

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
        A run whose energy ledger ``K + U + D - W_ext`` grows by more than this many times the
        scene's energy scale (:func:`initial_energy_scale`, from the initial state) is
        unstable too, even with bounded positions; checked over the saved samples once the
        run is through (a position blow-up stops the run first). The run is then reported
        as stopped at the first sample that grew: the error's step and time, ``stats``
        (steps, work and wall time counted up to that sample) and the kept samples all
        describe that one stopping point.
    stable_dt : float, optional
        Predicted stable step, quoted in the InstabilityError message.
    backend : {"auto", "numba", "numpy"}, optional
        Compiled or numpy stepping loop, fixed for the run (see :mod:`mslab.fast`); None reads
        ``$MSLAB_BACKEND`` (default ``"auto"``: compiled when the scene's effects all have
        kernels, the method has a compiled loop and the run is long enough to repay loading it).
    check_stability : bool
        For explicit methods, predict the largest stable dt first
        (:func:`mslab.stability.predicted_stable_dt`; not counted in ``stats``) and warn with
        :class:`~mslab.errors.StabilityWarning` when dt exceeds it; the run goes on, and a
        blow-up then quotes the prediction. Skipped above 5000 degrees of freedom.

    Returns
    -------
    Trajectory

    Raises
    ------
    InstabilityError
        The state became non-finite or blew up (``.trajectory`` keeps the saved part).
    ConvergenceError
        An implicit method's iteration failed.
    """
    backend = fast.check_backend(backend)
    s = scene.settings
    integrator = get_method(method if method is not None else s.method)
    dt = float(s.dt if dt is None else dt)
    t_end = float(s.t_end if t_end is None else t_end)
    save_every = int(s.save_every if save_every is None else save_every)
    if save_every < 1:
        raise ValueError(f"save_every must be >= 1, got {save_every}")
    n_steps = step_count(t_end, dt)
    if check_stability and integrator.explicit:
        stable_dt = _check_stability(scene, integrator, dt, stable_dt)
    system = scene.system
    saved = _save_indices(n_steps, save_every)
    n_saved = saved.size
    shape = (n_saved,) + scene.state0.x.shape
    try:
        xs, vs = np.empty(shape), np.empty(shape)
    except MemoryError:
        raise MemoryError(f"the {n_saved} saved samples need {2 * xs_bytes(shape) / 2**30:.3g} GiB; "
                          f"use a larger save_every or a shorter t_end") from None
    ds, ks, ps = np.empty(n_saved), np.empty(n_saved), np.empty(n_saved)
    ws = np.zeros(n_saved)  # external work: zero unless an effect drives
    limit = blowup * (1.0 + float(np.max(np.abs(scene.state0.x))))
    stats = Stats(method=integrator.name, dt=dt)
    runner = fast.stepper(system, integrator, backend, n_steps, scene.state0)
    stepped = system  # what the step-by-step loop below steps: the implicit methods' compiled path is
    if runner is not None and runner.view is not None:  # their own step on a compiled view
        stepped, runner = runner.view, None
    scale = initial_energy_scale(scene)  # 0: the run's own scale
    marks: list = [None] * n_saved  # (time, counters) when each sample was saved: where a run stops
    filled = 0  # samples [0, filled) have their kinetic and potential energy in ks, ps

    def energies(k: int) -> None:
        nonlocal filled
        for i in range(filled, k):  # the effects' own energies, whichever loop stepped
            ks[i], ps[i] = system.kinetic_energy(vs[i]), system.potential_energy(xs[i])
            if system.driving:
                ws[i] = system.external_work(xs[i], xs[0])
        filled = max(filled, k)

    def grown(first: int, k: int) -> int | None:
        """First sample in [first, k) whose ledger grew past ``energy_blowup`` x the scale."""
        if scale <= 0:
            return None
        energies(k)
        growth = (ks[first:k] + ps[first:k] + ds[first:k] - ws[first:k] - (ks[0] + ps[0] + ds[0])) / scale
        over = np.flatnonzero(~(growth <= energy_blowup))  # NaN counts as over
        return first + int(over[0]) if over.size else None

    def finish(k: int, complete: bool) -> Trajectory:
        energies(k)
        t = saved[:k] * dt
        if k == n_saved:  # the whole run: hand the arrays over, no copy (memory budget: 1 x)
            return Trajectory(t, xs, vs, Energy(ks, ps, ds, ws), stats, complete, scene.name)
        return Trajectory(t, xs[:k].copy(), vs[:k].copy(), Energy(ks[:k].copy(), ps[:k].copy(),
                          ds[:k].copy(), ws[:k].copy()), stats, complete, scene.name)

    def energy_error(j: int) -> InstabilityError:
        """Report the run as stopped at sample j, whose ledger grew.

        Steps, time and the work counted up to that sample (samples [0, j) kept).
        """
        step = int(saved[j])
        seconds, counted = marks[j]
        stats.wall_time, stats.steps = seconds - start, step
        for key, value in counted.items():
            setattr(stats, key, value - before[key])
        growth = (ks[j] + ps[j] + ds[j] - ws[j] - (ks[0] + ps[0] + ds[0])) / scale
        ledger = "K + U + D - W_ext" if system.driving else "K + U + D"
        return InstabilityError(
            f"{integrator.name} blew up by step {step} (t = {step * dt:.6g}, dt = {dt:g}): the state "
            f"stayed finite but the energy ledger {ledger} grew by {growth:.3g} x the scene's "
            f"energy scale{_hint(stable_dt)}", method=integrator.name, step=step, t=step * dt, dt=dt,
            stable_dt=stable_dt, trajectory=finish(j, False))

    from mslab.progress import make_progress

    bar, own_bar = make_progress(progress, n_steps, integrator.name)

    before = system.counters.snapshot()
    k = 0
    step = 0
    start = time.perf_counter()
    try:
        state = integrator.start(stepped, scene.state0, dt)
        xs[0], vs[0], ds[0] = state.x, state.v, state.dissipated
        marks[0] = (time.perf_counter(), system.counters.snapshot())
        k = 1
        while runner is not None and step < n_steps:  # compiled loop, in chunks (Ctrl-C, progress)
            done, k_done = step, k
            t0, c0 = time.perf_counter(), system.counters.snapshot()
            step, k, state, ok = runner.advance(state, dt, step, min(n_steps, step + runner.chunk),
                                                saved, k, xs, vs, ds, limit)
            t1 = time.perf_counter()
            # every compiled step costs the same number of force evaluations
            per_step = (system.counters.n_force - c0["n_force"]) // max(step - done, 1)
            for i in range(k_done, k):
                part = (saved[i] - done) / max(step - done, 1)
                marks[i] = (t0 + part * (t1 - t0),
                            {**c0, "n_force": c0["n_force"] + per_step * int(saved[i] - done)})
            if not ok:
                raise FloatingPointError
            if bar is not None:
                bar.update(step - done)
        for step in range(1, n_steps + 1) if runner is None else ():
            state = integrator.step(stepped, state, dt)
            if saved[k] == step:
                xs[k], vs[k], ds[k] = state.x, state.v, state.dissipated
                marks[k] = (time.perf_counter(), system.counters.snapshot())
                k += 1
            if not (np.isfinite(state.x).all() and np.isfinite(state.v).all()
                    and np.abs(state.x).max() < limit):
                raise FloatingPointError
            if bar is not None:
                bar.update(1)
    except FloatingPointError:  # step `step` failed: its work is counted, the run stops there
        _close(stats, system, before, start, step, bar if own_bar else None)
        k = int(np.searchsorted(saved, step - 1, side="right"))
        what = "non-finite" if not state.is_finite() else f"beyond {blowup:g} x the scene size"
        raise InstabilityError(
            f"{integrator.name} blew up at step {step} (t = {step * dt:.6g}, dt = {dt:g}): "
            f"state became {what}{_hint(stable_dt)}", method=integrator.name, step=step, t=step * dt,
            dt=dt, stable_dt=stable_dt, trajectory=finish(k, False)) from None
    except StepFailure as err:
        _close(stats, system, before, start, step, bar if own_bar else None)
        k = int(np.searchsorted(saved, step - 1, side="right"))
        raise ConvergenceError(
            f"{integrator.name} failed at step {step} (t = {step * dt:.6g}, dt = {dt:g}): {err}",
            method=integrator.name, step=step, t=step * dt, dt=dt, stable_dt=stable_dt,
            trajectory=finish(k, False)) from None
    except KeyboardInterrupt:
        _close(stats, system, before, start, step - 1, bar if own_bar else None)
        raise SimulationInterrupted(finish(k, False)) from None
    _close(stats, system, before, start, n_steps, bar if own_bar else None)
    if scale <= 0:  # nothing to compare with from the initial state: the run's own scale
        energies(k)
        scale = Energy(ks, ps, ds, ws).energy_scale()
    j = grown(0, k)
    if j is not None:
        raise energy_error(j)
    return finish(k, True)


def xs_bytes(shape: tuple) -> int:
    """Bytes of one float64 array of ``shape`` (the saved positions; velocities the same)."""
    return int(np.prod(shape, dtype=np.float64)) * 8


def _hint(stable_dt: float | None) -> str:
    if stable_dt is None:
        return "; try a smaller dt or an implicit method"
    if stable_dt == 0:
        return "; no dt is stable for this method on this scene: try an implicit or symplectic method"
    return f"; predicted stable dt = {stable_dt:.4g}"


def initial_energy_scale(scene: Scene) -> float:
    """Return an energy the scene's physics can never exceed by orders of magnitude, from the start.

    ``K0 + |U0| + sum_gravity m |g| L`` with ``L = 1 + max |x0|`` (the scene's size seen
    from the origin, where colliders usually sit): the initial kinetic and potential
    energy plus what gravity can release over that height. Computed from the initial
    state only, so a blow-up cannot inflate it. 0 for a scene at rest with nothing to
    release.
    """
    system, x0, v0 = scene.system, scene.state0.x, scene.state0.v
    size = 1.0 + float(np.max(np.abs(x0)))
    drop = sum(float(np.sum(e.mass[~system.pinned]) * np.linalg.norm(e.g)) * size
               for e in system.effects if isinstance(e, Gravity))
    return system.kinetic_energy(v0) + abs(system.potential_energy(x0)) + drop


def _energy_blowup_index(energy: Energy, factor: float, scale: float) -> int | None:
    """First saved sample whose ledger total exceeds E(0) by ``factor * scale``.

    The exact dynamics keeps ``K + U + D - W_ext`` constant, and no method of mslab is entitled to
    gain energy by orders of magnitude: such a run is unstable even when its positions stay
    bounded (a saturated instability, seen with forward Euler beyond its limit).
    """
    growth = (energy.total - energy.total[0]) / scale
    over = np.flatnonzero(~(growth <= factor))  # NaN counts as over
    return int(over[0]) if over.size else None


def _check_stability(scene: Scene, integrator: Integrator, dt: float, stable_dt: float | None):
    """Predicted stable dt (or the given one); warns when dt exceeds it. Counts no work."""
    from mslab.stability import predicted_stable_dt

    predicted = predicted_stable_dt(scene, integrator)
    if predicted is not None and dt > predicted:
        what = (f"{integrator.name} has no stable dt on this scene: its undamped oscillations grow "
                f"at every dt (slowly when dt is small)"
                if predicted == 0 else f"dt = {dt:g} exceeds the predicted stable dt = {predicted:.4g} "
                f"of {integrator.name} ({dt / predicted:.3g} x)")
        warnings.warn(f"{what}; the run may blow up", StabilityWarning, stacklevel=4)
    return predicted if stable_dt is None else stable_dt


def _close(stats: Stats, system: System, before: dict, start: float, steps: int, bar: object) -> None:
    stats.wall_time = time.perf_counter() - start
    stats.steps = max(steps, 0)  # steps taken; a failing step is counted with its work
    for key, value in system.counters.since(before).items():
        setattr(stats, key, value)
    if bar is not None:
        bar.close()
