"""A stepping session: advance a scene frame by frame, the same run as one long ``simulate`` call.

``Simulation(scene, method, dt)`` starts a run; ``advance(n)`` (or ``advance(t=...)``)
takes more steps; ``state``, ``t``, ``trajectory`` and ``stats`` describe it so far. Every
run of mslab is a session: :func:`mslab.simulate` is one ``advance`` of a session of
declared length. Advancing in any chunks gives bitwise the same positions, velocities,
energy ledger, counters and saved samples as one long call, on both backends: the session
holds the method's memory (Verlet's previous positions, leapfrog's half-step velocity,
a reused acceleration), the accumulated dissipated work, the blow-up checks' scales and the
compiled loop with its buffers; a call costs its steps, plus the ledger of the samples
it saves when they are read (:mod:`mslab.ledger`) and a ledger check every
:attr:`mslab.stopping.LedgerCheck.every` steps (:mod:`mslab.stopping`).

**Backend** (decided once per session, deterministically, never by timing): ``"numpy"``,
``"numba"``, or ``"auto"`` (default), decided when the session starts by
:func:`mslab.fast.worth_compiling` from the session's expected steps: its declared length
(``t_end``) when it has one (so a session and ``simulate()`` of the same length take the
same backend), else :data:`HORIZON` steps — so stepping a 64 x 64 cloth one frame at a time
gets the compiled loop, a five-particle chain the numpy one. Nothing read or advanced later
changes it.

**Owned data**: the session steps a private deep copy of the scene (system, effects, initial
state) and of the method, taken when it starts; it hands them out read-only (:mod:`mslab.owned`),
:attr:`Simulation.state` and :attr:`Simulation.stats` as copies. Editing the scene, the method
object or anything read from the session changes nothing in the run, on either backend.
``advance`` from a second thread while one runs is refused (RuntimeError).
"""

from __future__ import annotations

import copy
import threading
import time
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from mslab import fast, jit, stopping
from mslab.checks import flag, real, whole
from mslab.errors import ConvergenceError, InstabilityError, StepFailure
from mslab.initial import check_initial_state
from mslab.integrators.base import Integrator, get_method
from mslab.ledger import NEVER, Samples, initial_energy_scale
from mslab.owned import read_only, read_only_arrays, samples_trajectory
from mslab.state import State
from mslab.stepping import CompiledLoop, LedgerOver, NumpyLoop, interpolate_marks
from mslab.steps import check_dt, step_count, steps_to_take
from mslab.stopping import LedgerCheck, hint, position_limit
from mslab.trajectory import Stats, Trajectory

if TYPE_CHECKING:
    from mslab.scene import Scene

#: steps a session of unknown length is expected to take, for ``backend="auto"``: about three
#: seconds of frames of 16 substeps at 60 frames per second
HORIZON = 3000


class SimulationInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run: ``.trajectory`` holds what was computed."""

    def __init__(self, trajectory: Trajectory):
        super().__init__("interrupted")
        self.trajectory = trajectory


class Simulation:
    """A stepping session over one scene with one method and a fixed step.

    Parameters
    ----------
    scene : Scene
    method : str or Integrator, optional
        Registry name (see ``mslab.methods()``); default ``scene.settings.method``.
    dt : float, optional
        The step; default ``scene.settings.dt``. Validated here, once.
    t_end : float, optional
        Declared length (``t_end / dt`` a whole number of steps): the run may not go
        beyond, its last step is saved and ledger-checked, and ``auto`` weighs its length.
        None: open-ended.
    save_every : int, optional
        Save every n-th step (and the declared end). Default: ``scene.settings.save_every``
        with a ``t_end``; an open-ended session saves only its first state (hours of frames
        fill no memory). ``trajectory`` adds the current state when it is not a saved step.
    blowup, energy_blowup, stable_dt, check_stability, backend, threads, dtype
        As in :func:`mslab.simulate`.

    Everything read from a session leaves the run as it is (:mod:`mslab.owned`): its settings,
    ``system`` and ``integrator`` are read-only attributes whose arrays are read-only, ``stats``
    and ``state`` are copies, ``trajectory`` copies or read-only views.
    """

    def __init__(self, scene: Scene, method: str | Integrator | None = None, dt: float | None = None, *,
                 t_end: float | None = None, save_every: int | None = None, blowup: float = 1e6,
                 stable_dt: float | None = None, backend: str | None = None, check_stability: bool = True,
                 energy_blowup: float = 1e4, threads: int | None = None, dtype: str = "float64",
                 _stacklevel: int = 2):
        from mslab.scene import Scene, own_copy

        if not isinstance(scene, Scene):
            raise TypeError(f"scene must be an mslab Scene, got {type(scene).__name__}")
        check_initial_state(scene)  # cheap, before the copy and any set-up
        s = scene.settings
        if backend is not None and not isinstance(backend, str):
            raise TypeError(f"backend must be a string or None, got {type(backend).__name__}")
        self._backend = fast.check_backend(backend)
        self._dtype = fast.check_dtype(dtype, self.backend)  # float32: the compiled loop only
        self._threads = jit.thread_count(None if threads is None else whole("threads", threads, 1))
        self._user_scene = scene  # the user's: the run steps its own copy (editing the scene changes nothing)
        own = own_copy(scene)
        self._scene, self._system = own, own.system
        if method is not None and not isinstance(method, (str, Integrator)):
            raise TypeError(f"method must be a method name or an Integrator, got {type(method).__name__}")
        self._integrator = copy.deepcopy(get_method(method if method is not None else s.method))
        self._dt = check_dt(s.dt if dt is None else dt)
        self._end = None if t_end is None else step_count(t_end, self.dt)
        if save_every is None:  # open-ended: only the first state (hours of frames fill no memory)
            save_every = s.save_every if self.end is not None else NEVER
        self._save_every = whole("save_every", save_every, 1)
        blowup = real("blowup", blowup, positive=True, allow_inf=True)
        energy_blowup = real("energy_blowup", energy_blowup, positive=True, allow_inf=True)
        stable_dt = None if stable_dt is None else real("stable_dt", stable_dt, minimum=0.0)  # 0: none
        check_stability = flag("check_stability", check_stability)
        state0 = own.state0
        self._blowup = blowup
        self._stable_dt = stable_dt
        if check_stability and self.integrator.explicit:
            self._stable_dt = stopping.check_stability(scene, self.integrator, self.dt, stable_dt,
                                                      stacklevel=_stacklevel + 1)
        self._stats = Stats(method=self.integrator.name, dt=self.dt)
        self._samples = Samples(self.system, state0.x.shape, self.save_every, self.end)
        beyond = stopping.beyond_limit(own, self.integrator, self.dt, self.stable_dt)
        self._check = LedgerCheck(initial_energy_scale(own), energy_blowup, self.integrator.n_stages,
                                  self.end, own, beyond)
        self._limit = position_limit(own, blowup)
        self._loop: NumpyLoop | CompiledLoop | None = None
        self._failed: Exception | None = None
        self._running = threading.Lock()
        self._begin()  # the backend and the method's start: fixed when the session starts
        mine = [] if own.system is scene.system else [own.system, *own.system.effects]  # (replaced forces)
        read_only_arrays(self._integrator, *mine)  # after the compiled loop took its parameters

    # -- what the session is at (read-only: fixed when it starts) ------------------------------
    scene = read_only("user_scene", "The scene the session started from (the user's; the run steps a copy).")
    system = read_only("system", "The session's own copy of the system (its public arrays read-only).")
    integrator = read_only("integrator", "The session's own copy of the method (its arrays read-only).")
    dt = read_only("dt", "The step.")
    end = read_only("end", "The declared length in steps (None: open-ended).")
    save_every = read_only("save_every", "Every how many steps a state is saved.")
    backend = read_only("backend", "The backend asked for (``compiled`` says which loop steps).")
    dtype = read_only("dtype", "The precision of the stepping loop.")
    threads = read_only("threads", "Threads of the compiled loops.")
    blowup = read_only("blowup", "Positions beyond this many times the scene's size are a blow-up.")
    stable_dt = read_only("stable_dt", "The predicted stable step quoted in errors (None: unknown).")

    @property
    def stats(self) -> Stats:
        """A copy of the session's cumulative work and stepping time (editing it changes nothing)."""
        return replace(self._stats)

    @property
    def step(self) -> int:
        """Steps taken so far."""
        return 0 if self._loop is None else self._loop.step

    @property
    def t(self) -> float:
        """Time reached: ``step * dt``."""
        return self.step * self.dt

    @property
    def state(self) -> State:
        """A copy of the current state (positions, velocities, the method's memory) on every backend."""
        state = self._loop.state()
        return replace(state, x=state.x.copy(), v=state.v.copy(),
                       memory=tuple(np.array(m, copy=True) for m in state.memory))

    @property
    def compiled(self) -> bool:
        """Whether the compiled loop steps this session (decided when it starts)."""
        return isinstance(self._loop, CompiledLoop) or self._stepped is not self.system

    @property
    def trajectory(self) -> Trajectory:
        """The saved samples so far, and the current state when it is not one of them."""
        if self._failed is not None:
            return self._failed.trajectory
        return self._trajectory(self._samples.k, True, current=True)

    def __repr__(self) -> str:
        """Return a one-line summary (scene, method, dt, steps, loop), never the arrays."""
        end = self.end
        length = f"{self.step} of {end} steps" if end is not None else f"{self.step} steps, open-ended"
        stopped = ", stopped" if self._failed is not None else ""
        return (f"Simulation({self._scene.name!r}: {self.integrator.name} dt={self.dt:g}, {length}, "
                f"{'compiled' if self.compiled else 'numpy'} loop{stopped})")

    # -- stepping ------------------------------------------------------------------------------
    def advance(self, n: int | None = None, *, t: float | None = None, progress: object = False) -> None:
        """Take ``n`` more steps (or ``t`` more seconds, a whole number of steps; neither: to ``t_end``).

        Returns nothing: read :attr:`state` (a copy) when needed, so a call costs its steps.
        Raises InstabilityError or ConvergenceError where the
        run fails (``.trajectory`` keeps the samples before the failing step; the session
        then stays stopped), SimulationInterrupted on Ctrl-C. ``progress`` as in
        :func:`mslab.simulate`.
        """
        if not self._running.acquire(blocking=False):
            raise RuntimeError("advance is already running on this session in another thread; a session "
                               "steps one call at a time (wait for it, or use one session per thread)")
        try:
            self._advance_locked(n, t, progress)
        finally:
            self._running.release()

    def _advance_locked(self, n: int | None, t: float | None, progress: object) -> None:
        if self._failed is not None:
            raise ValueError(f"the session stopped at step {self.step}: {self._failed}")
        count = steps_to_take(n, t, self.dt, self.step, self.end)
        if self.end is not None and self.step + count > self.end:
            raise ValueError(f"the session ends at step {self.end} (t_end); {count} more steps from "
                             f"step {self.step} go beyond")
        self._samples.refuse_beyond(self.step + count)  # (open-ended, save_every given: memory grows)
        if self.integrator.implicit:  # Newton's small solves: threads only cost time (mslab.threads)
            from mslab.threads import single_threaded_blas

            with jit.threads(self.threads):
                single_threaded_blas(self._advance)(count, progress)
        else:
            with jit.threads(self.threads):
                self._advance(count, progress)

    def _begin(self) -> None:
        """Choose the loop (``auto``: from the declared length, else :data:`HORIZON`) and start the method."""
        expected = self.end if self.end is not None else HORIZON
        runner = fast.stepper(self.system, self.integrator, self.backend, expected, self._scene.state0,
                              self.dtype)
        self._stepped = self.system  # the implicit methods' compiled path steps their own
        if runner is not None and runner.view is not None:  # numpy code on a compiled view
            self._stepped, runner = runner.view, None
        before, start = self.system.counters.snapshot(), time.perf_counter()
        state = self.integrator.start(self._stepped, self._scene.state0, self.dt)
        self._account(before, start)
        self._samples.add(state.x, state.v, state.dissipated, self._totals())
        self._check.start(float(self._samples.energy(1, copy=False).total[0]))
        if runner is None:
            self._loop = NumpyLoop(self.integrator, self._stepped, state, self.dt, self._limit)
        else:
            self._loop = CompiledLoop(runner, state, self.dt, self._limit)

    def _advance(self, count: int, progress: object) -> None:
        from mslab.progress import make_progress

        loop, samples, check = self._loop, self._samples, self._check
        target, k_done = loop.step + count, samples.k
        bar, own_bar = make_progress(progress, target - loop.step, self.integrator.name)
        before, start = self.system.counters.snapshot(), time.perf_counter()
        base = self._totals()

        def mark() -> tuple:  # the session's stepping time and counters now
            now = self.system.counters.snapshot()
            return (base[0] + time.perf_counter() - start, {k: base[1][k] + now[k] - before[k] for k in now})

        try:
            while loop.step < target:
                done, k_done = loop.step, samples.k
                stop = min(target, check.next_due(done), done + loop.chunk)
                samples.reserve(stop)
                begun = mark() if isinstance(loop, CompiledLoop) else None
                ok = loop.run(stop, samples, mark)
                if begun is not None:
                    interpolate_marks(samples, k_done, done, loop.step, begun, mark())
                # one order of events per step, whatever the chunks: a saved sample's ledger over
                # the bound, then a position blow-up (at the step it happened), then the periodic check
                self._raise_over(k_done, None if ok else loop.step)
                if not ok:
                    raise FloatingPointError
                if check.due(loop.step):
                    self._check_ledger()
                if bar is not None:
                    bar.update(loop.step - done)
        except FloatingPointError:  # step loop.step failed: its work is counted, the run stops there
            self._account(before, start, bar if own_bar else None)
            state = loop.state()
            what = "non-finite" if not state.is_finite() else f"beyond {self.blowup:g} x the scene size"
            raise self._stop(InstabilityError, f"blew up at step {loop.step}", f"state became {what}"
                             f"{hint(self.stable_dt)}") from None
        except _LedgerGrew as grew:
            self._account(before, start, bar if own_bar else None)
            ledger = "K + U + D - W_ext" if self.system.driving else "K + U + D"
            raise self._stop(InstabilityError, f"blew up by step {loop.step}", f"the state stayed finite "
                             f"but the energy ledger {ledger} {grew}{hint(self.stable_dt)}") from None
        except LedgerOver as over:
            self._account(before, start, bar if own_bar else None)
            raise self._ledger_stop(over.j) from None
        except StepFailure as err:
            self._account(before, start, bar if own_bar else None)
            j = self._over(k_done, loop.step + 1)  # a sample over the bound before the failing step
            if j is not None:
                raise self._ledger_stop(j) from None
            raise self._stop(ConvergenceError, f"failed at step {loop.step + 1}", str(err),
                             step=loop.step + 1) from None
        except KeyboardInterrupt:
            self._account(before, start, bar if own_bar else None)
            raise SimulationInterrupted(self._trajectory(samples.k, False, current=False)) from None
        self._account(before, start, bar if own_bar else None)

    def _totals(self) -> tuple:
        """Return the session's stepping time and counters so far (a sample's mark)."""
        return self._stats.wall_time, {k: getattr(self._stats, k) for k in self.system.counters.snapshot()}

    def _over(self, first: int, before_step: int | None = None) -> int | None:
        """Return the first sample from ``first`` (before step ``before_step``) whose ledger gained too much.

        Checked on the samples each stretch of steps saved, before that stretch's position
        blow-up (which stops at its own step, not at a sample of it) and its periodic check.
        """
        samples, check = self._samples, self._check
        if not check.on or samples.k <= first:
            return None
        k = samples.k
        if before_step is not None:
            k = int(np.searchsorted(samples.steps[:k], before_step, side="left"))
            if k <= first:
                return None
        energy = samples.energy(samples.k, copy=False)
        scale = check.scale if check.scale > 0 else energy.energy_scale()  # at rest: the run's own
        return check.over(energy.total[:k], first, scale)

    def _raise_over(self, first: int, before_step: int | None) -> None:
        j = self._over(first, before_step)
        if j is not None:
            raise LedgerOver(j)

    def _ledger_stop(self, j: int) -> Exception:
        """Return the error that stops the run at sample ``j``, whose ledger gained over ``energy_blowup``."""
        samples = self._samples
        energy = samples.energy(samples.k, copy=False)
        check = self._check
        scale = check.scale if check.scale > 0 else energy.energy_scale()
        step = int(samples.steps[j])
        self._stats.wall_time, counted = samples.marks[j]
        for key, value in counted.items():
            setattr(self._stats, key, value)
        growth = (energy.total[j] - energy.total[0]) / scale
        ledger = "K + U + D - W_ext" if self.system.driving else "K + U + D"
        return self._stop(InstabilityError, f"blew up by step {step}", f"the state stayed finite but the "
                         f"energy ledger {ledger} grew by {growth:.3g} x the scene's energy scale"
                         f"{hint(self.stable_dt)}", step=step, keep=j)

    def _check_ledger(self) -> None:
        loop, system = self._loop, self.system
        x, v = loop.x, loop.v  # (a compiled loop's are copies: read once)
        kinetic = float(system.kinetic_energy(v, self.compiled))
        total = kinetic + float(system.potential_energy(x, self.compiled)) + loop.dissipated
        if system.driving:
            total -= float(system.external_work(x, self._samples.x[0]))
        reason = self._check.check(loop.step, total, kinetic, x, v)
        if reason is not None:
            raise _LedgerGrew(reason)

    def _account(self, before: dict, start: float, bar: object = None) -> None:
        """Add the work counted since ``before`` and the time since ``start`` to :attr:`stats`."""
        stats = self._stats
        stats.wall_time += time.perf_counter() - start
        stats.steps = self.step
        for key, value in self.system.counters.since(before).items():
            setattr(stats, key, getattr(stats, key) + value)
        if bar is not None:
            bar.close()

    def _stop(self, kind: type, what: str, detail: str, step: int | None = None,
              keep: int | None = None) -> Exception:
        """Return the error that stops the session at ``step`` (default: the current one).

        The trajectory keeps the samples before ``step`` (or the first ``keep``).
        """
        step = self.step if step is None else step
        stats = self._stats
        stats.steps = step
        name, dt = self.integrator.name, self.dt
        if keep is None:
            keep = int(np.searchsorted(self._samples.steps[: self._samples.k], step - 1, side="right"))
        err = kind(f"{name} {what} (t = {step * dt:.6g}, dt = {dt:g}): {detail}", method=name, step=step,
                   t=step * dt, dt=dt, stable_dt=self.stable_dt, trajectory=self._trajectory(keep, False))
        self._failed = err
        return err

    def _trajectory(self, k: int, complete: bool, current: bool = False,
                    handover: bool = False) -> Trajectory:
        """Return samples ``[0, k)`` and the current state when ``current`` (:func:`samples_trajectory`)."""
        return samples_trajectory(self._samples, self._loop, replace(self._stats), self.dt, self._scene.name,
                                  k, complete, current, handover)


class _LedgerGrew(Exception):
    """The ledger check found growth (internal: turned into InstabilityError)."""
