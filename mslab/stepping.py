"""The two stepping loops of a session, one interface: numpy (the readable reference) and compiled.

Both take steps ``step+1 .. stop`` from the state they hold, save the states whose step is
in the session's save grid (:class:`mslab.ledger.Samples`), test every step for a blow-up
of the positions and stop there, and count the work on the System. Neither knows about
sessions, time or errors: :class:`mslab.simulation.Simulation` drives them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Callable

    from mslab.fast.runner import Stepper
    from mslab.integrators.base import Integrator
    from mslab.ledger import Samples
    from mslab.state import State
    from mslab.system import System


class NumpyLoop:
    """``integrator.step`` on ``system`` (the System, or the compiled view of an implicit method)."""

    #: steps between two returns to the session (progress bar)
    chunk = 256

    def __init__(self, integrator: Integrator, system: System, state: State, dt: float, limit: float):
        self.integrator, self.system, self.dt, self.limit = integrator, system, dt, limit
        self._state = state
        self.step = 0

    @property
    def x(self) -> np.ndarray:
        """Current positions."""
        return self._state.x

    @property
    def v(self) -> np.ndarray:
        """Current velocities."""
        return self._state.v

    @property
    def dissipated(self) -> float:
        """Dissipated work so far."""
        return self._state.dissipated

    def state(self) -> State:
        """Return the current state (immutable: no copy needed)."""
        return self._state

    def run(self, stop: int, samples: Samples, mark: Callable[[], tuple]) -> bool:
        """Take steps up to ``stop``; False when step :attr:`step` blew up. ``mark()``: see Samples."""
        step, state, steps, k = self.step, self._state, samples.steps, samples.k
        while step < stop:
            state = self.integrator.step(self.system, state, self.dt)
            step += 1
            self._state, self.step = state, step
            if k < steps.size and steps[k] == step:
                samples.add(state.x, state.v, state.dissipated, mark())
                k += 1
            if not (np.isfinite(state.x).all() and np.isfinite(state.v).all()
                    and np.abs(state.x).max() < self.limit):
                return False
        return True


class CompiledLoop:
    """The family's compiled loop (:class:`mslab.fast.runner.Stepper`), holding the state in its arrays."""

    def __init__(self, runner: Stepper, state: State, dt: float, limit: float):
        self.runner, self.dt, self.limit = runner, dt, limit
        runner.load(state)
        self.step = 0
        self.chunk = runner.chunk

    @property
    def x(self) -> np.ndarray:
        """Current positions, a float64 copy (the loop keeps its state coordinate-major)."""
        return self.runner.x

    @property
    def v(self) -> np.ndarray:
        """Current velocities, a float64 copy (the loop keeps its state coordinate-major)."""
        return self.runner.v

    @property
    def dissipated(self) -> float:
        """Dissipated work so far."""
        return self.runner.dissipated

    def state(self) -> State:
        """Return a copy of the current state."""
        return self.runner.state()

    def run(self, stop: int, samples: Samples, mark: Callable[[], tuple]) -> bool:
        """Take steps up to ``stop``; False when step :attr:`step` blew up (marks: the session's)."""
        self.step, samples.k, ok = self.runner.run(self.dt, self.step, stop, samples.steps, samples.k,
                                                   samples.x, samples.v, samples.d, self.limit)
        return ok


def interpolate_marks(samples: Samples, k_done: int, done: int, step: int, begun: tuple,
                       ended: tuple) -> None:
    """Add the marks of the samples a compiled call saved (every compiled step costs the same)."""
    (t0, c0), (t1, _) = begun, ended
    per_step = (ended[1]["n_force"] - c0["n_force"]) // max(step - done, 1)
    for i in range(k_done, samples.k):
        part = (samples.steps[i] - done) / max(step - done, 1)
        counted = {**c0, "n_force": c0["n_force"] + per_step * int(samples.steps[i] - done)}
        samples.marks.append((t0 + part * (t1 - t0), counted))


class LedgerOver(Exception):
    """A saved sample's ledger gained over the bound (internal: turned into InstabilityError)."""

    def __init__(self, j: int):
        super().__init__(j)
        self.j = j
