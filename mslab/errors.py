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


class PerformanceWarning(UserWarning):
    """A run takes a slower path than it could (e.g. numba is not installed)."""


class BrokenFileWarning(UserWarning):
    """A method or effect file could not be loaded; it is skipped and everything else works.

    The message is one line ``FILE:LINE: reason`` (:func:`failure_line`).
    """


def failure_line(err: BaseException, path: str) -> str:
    """One line ``FILE:LINE: reason`` for an exception raised while importing the file ``path``.

    The line is where the error arose in that file: a syntax error's own line, otherwise the
    last frame of the traceback inside ``path`` (the ``register(...)`` call of a refused
    method, the statement of a NameError).
    """
    import os
    import traceback

    lineno = getattr(err, "lineno", None) if isinstance(err, SyntaxError) else None
    if lineno is None:
        here = os.path.realpath(path)
        frames = [f for f in traceback.extract_tb(err.__traceback__)
                  if os.path.realpath(f.filename) == here]
        lineno = frames[-1].lineno if frames else 1
    text = str(err).splitlines()[0].strip() if str(err).strip() else ""
    if isinstance(err, SyntaxError):
        reason = f"SyntaxError: {err.msg}"
    elif isinstance(err, ValueError) and text:  # a refusal that explains itself
        reason = text
    else:
        reason = f"{type(err).__name__}: {text}" if text else type(err).__name__
    return f"{path}:{lineno}: {reason}"


#: one line per method or effect file that failed to load, and whether it was reported
_BROKEN: dict[str, bool] = {}


def note_broken(line: str) -> None:
    """Record a file that failed to load (``FILE:LINE: reason``); reported on the next lookup."""
    _BROKEN.setdefault(line, False)


def broken_files() -> list[str]:
    """Every method or effect file that failed to load, one line each."""
    return list(_BROKEN)


def warn_broken(stacklevel: int = 3) -> None:
    """Issue a :class:`BrokenFileWarning` for each failed file not reported yet."""
    import warnings

    for line, done in list(_BROKEN.items()):
        if not done:
            _BROKEN[line] = True
            warnings.warn(f"{line} (file skipped)", BrokenFileWarning, stacklevel=stacklevel)


def take_broken() -> list[str]:
    """Return the failed files not reported yet and mark them reported (for the command line)."""
    lines = [line for line, done in _BROKEN.items() if not done]
    for line in lines:
        _BROKEN[line] = True
    return lines
