"""Cells a student completes in a lesson, checked at once with a one-line answer.

A lesson stores its exercise cells *unsolved*: the student's line holds ``TODO`` and the check
below it prints ``not done yet: ...`` (deterministic, so nbval passes and no solution is
shown). Once the student fills it in, the same check prints ``right: ...`` or a one-line hint,
never a traceback::

    from mslab.exercise_cells import TODO, check_function, check_prediction

    def euler_step(f, t, y, h):
        return TODO                                  # your line: one forward Euler step

    check_function("euler_step", euler_step, reference=lambda f, t, y, h: ...,
                   cases=[(f, 0.0, 1.0, 0.1)],
                   mistakes={"you evaluated f at the new point": lambda f, t, y, h: ...})

A prediction is written down before a run and compared with what the run measures::

    my_guess = TODO                                  # e.g. "grows", "bounded", "decays"
    ... run ...
    check_prediction(my_guess, measured="grows", choices=("grows", "bounded", "decays"))

The reference a check compares with is computed (from the library or from an independent
formula), so the cell shows how the answer is checked, not the line the student writes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["TODO", "check_value", "check_function", "check_prediction"]


class _Todo:
    """The placeholder a student replaces."""

    def __repr__(self) -> str:
        return "TODO"

    def __call__(self, *args: object, **kwargs: object) -> _Todo:
        return self


TODO = _Todo()


def _is_todo(value: object) -> bool:
    return value is TODO or (isinstance(value, (tuple, list)) and any(v is TODO for v in value))


def _close(a: object, b: object, rtol: float, atol: float) -> bool:
    """Equal to the tolerances, also for nested sequences of different lengths (a tableau's A and b)."""
    try:
        a_arr, b_arr = np.asarray(a, dtype=complex), np.asarray(b, dtype=complex)
    except (TypeError, ValueError):
        if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)) and len(a) == len(b):
            return all(_close(x, y, rtol, atol) for x, y in zip(a, b, strict=True))
        return False
    return a_arr.shape == b_arr.shape and bool(np.allclose(a_arr, b_arr, rtol=rtol, atol=atol))


def _say(line: str) -> None:
    print(line)


def check_value(name: str, answer: object, expected: object, *, rtol: float = 1e-6, atol: float = 0.0,
                mistakes: dict[str, object] | None = None) -> None:
    """Print whether ``answer`` equals ``expected`` (a number or array, to ``rtol``/``atol``).

    ``mistakes`` maps a one-line hint to the value a common mistake gives. Returns None, so a
    notebook cell ending with the call shows the one line only.
    """
    if _is_todo(answer):
        return _say(f"not done yet: replace TODO in {name} and run the cell again")
    if _close(answer, expected, rtol, atol):
        return _say(f"right: {name} is correct")
    for hint, wrong in (mistakes or {}).items():
        if _close(answer, wrong, rtol, atol):
            return _say(f"not yet right: {hint}")
    return _say(f"not yet right: {name} differs from the expected value; check each term")


def check_function(name: str, fn: Callable, *, reference: Callable, cases: Sequence[tuple],
                   mistakes: dict[str, Callable] | None = None, rtol: float = 1e-10,
                   atol: float = 1e-12) -> None:
    """Call ``fn`` and ``reference`` on every case; print one line: right, a hint, or not done yet.

    ``mistakes`` maps a one-line hint to a function that makes that common mistake; when the
    student's results match one of them on every case, its hint is printed. An exception of the
    student's code is reported in one line.
    """
    got = []
    for case in cases:
        try:
            value = fn(*case)
        except Exception as exc:  # noqa: BLE001  (a student's code: report, never a traceback)
            return _say(f"not yet right: {name}{tuple(case)!r:.60} raised {type(exc).__name__}: {exc}")
        if _is_todo(value):
            return _say(f"not done yet: replace TODO in {name} and run the cell again")
        got.append(value)
    if all(_close(g, reference(*c), rtol, atol) for g, c in zip(got, cases, strict=True)):
        return _say(f"right: {name} agrees with the reference on {len(cases)} case(s)")
    for hint, wrong in (mistakes or {}).items():
        if all(_close(g, wrong(*c), rtol, atol) for g, c in zip(got, cases, strict=True)):
            return _say(f"not yet right: {hint}")
    return _say(f"not yet right: {name} differs from the reference; compare it term by term with the formula")


def check_prediction(guess: object, *, measured: str, choices: Sequence[str]) -> None:
    """Print the measured outcome next to the student's prediction (one of ``choices``).

    Until the student has predicted (``guess`` is ``TODO``) the measured outcome is not shown: the
    stored output a student opens must not answer the question a few lines above it.
    """
    if _is_todo(guess):
        return _say(f"not done yet: write your prediction (one of {', '.join(map(repr, choices))}) "
                    "and run this cell again: the measured outcome is shown next to it")
    if str(guess).strip().lower() not in choices:
        return _say(f"not yet right: a prediction is one of {', '.join(map(repr, choices))}")
    if str(guess).strip().lower() == measured:
        return _say(f"right: you predicted {measured!r}, and that is what the run shows")
    return _say(f"not yet right: you predicted {guess!r}; the run shows {measured!r}: why?")


def explorer(draw: Callable, *controls: object) -> object:
    """Return controls above an output, redrawn by ``draw(*values)`` whenever a control moves.

    Building it draws nothing, so a headless run (nbval, nbclient) never waits on it; the box
    carries the CSS class of ``ipywidgets.interactive`` (``widget-interact``), which it replaces
    (``display(interactive(...))`` ran ``draw`` at once inside its output and held a headless
    run for the whole cell timeout).
    """
    import ipywidgets as widgets

    view = widgets.Output()

    def redraw(change: object = None) -> None:
        with view:
            view.clear_output(wait=True)
            draw(*(c.value for c in controls))

    for c in controls:
        c.observe(redraw, "value")
    box = widgets.VBox([widgets.HBox(list(controls)), view])
    box.add_class("widget-interact")
    return box
