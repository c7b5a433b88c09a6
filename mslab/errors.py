"""Errors and warnings raised by mslab."""

from __future__ import annotations

from typing import Any


class MslabError(Exception):
    """Base class of every error mslab raises on purpose."""


class SceneError(MslabError, ValueError):
    """A scene description is invalid.

    ``key`` names the offending entry (``"springs.stiffness"``), ``source`` the file.
    """

    def __init__(self, key: str, reason: str, source: str | None = None):
        self.key = key
        self.reason = reason
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}{key}: {reason}")


class StepFailure(MslabError):
    """Raised inside an integrator's ``step`` when one step cannot be completed.

    ``simulate`` turns it into a :class:`ConvergenceError` that knows the step, time
    and dt.
    """


class InstabilityError(MslabError, FloatingPointError):
    """A run blew up: the state became non-finite or grew without bound.

    Attributes
    ----------
    method, step, t, dt : the run and the step at which it was stopped.
    stable_dt : float or None
        The predicted largest stable step for this scene and method, when known.
    trajectory : mslab.trajectory.Trajectory or None
        Everything saved up to the last good step (typed ``Any`` here: errors are a leaf
        module and import nothing of mslab).
    """

    def __init__(self, message: str, *, method: str = "", step: int = 0, t: float = 0.0,
                 dt: float = 0.0, stable_dt: float | None = None, trajectory: Any = None):
        super().__init__(message)
        self.method = method
        self.step = step
        self.t = t
        self.dt = dt
        self.stable_dt = stable_dt
        self.trajectory = trajectory


class ConvergenceError(InstabilityError):
    """An implicit method's iteration (fixed-point or Newton) did not converge."""


class StabilityWarning(UserWarning):
    """The chosen dt exceeds the predicted stable step; the run goes on."""
