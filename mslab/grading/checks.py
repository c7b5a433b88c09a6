"""Assertions for exercise tests: the same messages whether run locally or while grading.

While grading, the student's answers arrive as decoded data and the student's exceptions
as :class:`~mslab.grading.remote.StudentError`; locally they are the real thing. These
helpers accept both and fail with one clear line (shape, dtype, worst error).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from mslab.grading.remote import StudentError

if TYPE_CHECKING:
    import numpy.typing as npt

    from mslab.grading.problems import Problem
    from mslab.state import State


def check_shape(out: Any, shape: tuple, what: str = "result") -> None:
    """``out`` must be a floating-point ndarray of the given shape."""
    if not isinstance(out, np.ndarray):
        raise AssertionError(f"{what}: expected a numpy array of shape {shape}, got {type(out).__name__}")
    if out.shape != tuple(shape):
        raise AssertionError(f"{what}: shape {out.shape}, expected {tuple(shape)}")
    if out.dtype.kind not in "fc":
        raise AssertionError(f"{what}: dtype {out.dtype}, expected a floating-point array")


def as_numbers(value: Any, shape: tuple | None = None, what: str = "result") -> np.ndarray:
    """Return the student's numbers as a float array, reading no text; AssertionError otherwise.

    Accepts a real numeric ndarray or nested lists/tuples of ints and floats (of at most
    ``shape`` when given). Strings are refused, never parsed (the trust boundary: nothing
    the student answered is read by a parser that could execute or expand it).
    """
    def first_bad(v: Any, depth: int) -> str | None:
        """Return the type of the first entry that is not a number (None if all are)."""
        if isinstance(v, np.ndarray):
            return None if v.dtype.kind in "iuf" else f"an array of {v.dtype}"
        if isinstance(v, list | tuple):
            if depth >= 8:
                return "lists nested too deeply"
            return next((b for w in v if (b := first_bad(w, depth + 1)) is not None), None)
        if isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool | np.bool_):
            return None
        return type(v).__name__

    bad = first_bad(value, 0) if isinstance(value, np.ndarray | list | tuple) else type(value).__name__
    if bad is not None:
        inside = "" if not isinstance(value, list | tuple) else f" inside a {type(value).__name__}"
        raise AssertionError(f"{what}: expected numbers, got {bad}{inside}")
    try:
        out = np.array(value, dtype=float)
    except ValueError:
        raise AssertionError(f"{what}: a ragged nest of lists, not an array") from None
    if shape is not None and out.shape != tuple(shape):
        raise AssertionError(f"{what}: shape {out.shape}, expected {tuple(shape)}")
    return out


def as_count(value: Any, what: str = "result") -> int:
    """Return the student's whole number (an int, or a float with an integer value) as an int."""
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise AssertionError(f"{what}: expected a whole number, got {type(value).__name__}")
    if not np.isfinite(value) or value != int(value):
        raise AssertionError(f"{what}: expected a whole number, got {value!r}")
    return int(value)


def check_array(out: Any, expected: npt.ArrayLike, rtol: float = 1e-10, atol: float = 1e-12,
                what: str = "result") -> None:
    """``out`` must be a float ndarray of the expected shape, finite, and close to ``expected``."""
    expected = np.asarray(expected)
    if not isinstance(out, np.ndarray):
        raise AssertionError(f"{what}: expected a numpy array of shape {expected.shape}, "
                             f"got {type(out).__name__}")
    if out.shape != expected.shape:
        raise AssertionError(f"{what}: shape {out.shape}, expected {expected.shape}")
    kinds = "fc" if expected.dtype.kind == "c" else "f"
    if out.dtype.kind not in kinds:
        raise AssertionError(f"{what}: dtype {out.dtype}, expected a floating-point array")
    if not np.all(np.isfinite(out)):
        raise AssertionError(f"{what}: contains NaN or inf")
    err = np.abs(out - expected)
    bound = atol + rtol * np.abs(expected)
    if np.any(err > bound):
        k = int(np.argmax(err - bound))
        raise AssertionError(f"{what}: wrong values (worst error {err.flat[k]:.3g} at flat index {k}, "
                             f"allowed {bound.flat[k]:.3g})")


def check_scalar(out: Any, expected: float, rtol: float = 1e-10, atol: float = 1e-12,
                 what: str = "result", mistakes: dict[str, float] | None = None) -> None:
    """``out`` must be a real number close to ``expected``; a known mistake's value is named.

    ``mistakes`` maps a one-line hint to the value that mistake gives (compared only once
    the answer is wrong, as in :func:`check_known`).
    """
    if isinstance(out, np.ndarray) and out.shape == ():
        out = out.item()
    if isinstance(out, bool) or not isinstance(out, int | float | np.integer | np.floating):
        raise AssertionError(f"{what}: expected a number, got {type(out).__name__}")
    if not abs(float(out) - expected) <= atol + rtol * abs(expected):
        hint = next((h for h, w in (mistakes or {}).items()
                     if np.isclose(float(out), w, rtol=1e-8, atol=1e-10)), None)
        tail = f": likely mistake: {hint}" if hint else ""
        raise AssertionError(f"{what}: {float(out):.12g}, expected {expected:.12g}{tail}")


def raised(err: BaseException, exc_type: type[BaseException]) -> bool:
    """Tell whether the student's code raised ``exc_type`` (locally or in the sandbox).

    ``NotImplementedError`` (the untouched release) never counts, though it is a RuntimeError.
    """
    if isinstance(err, StudentError):
        return exc_type.__name__ in err.mro and "NotImplementedError" not in err.mro
    return isinstance(err, exc_type) and not isinstance(err, NotImplementedError)


def check_raises(exc_type: type[BaseException], func: Callable, *args, **kwargs) -> None:
    """``func(*args, **kwargs)`` must raise ``exc_type`` (not NotImplementedError)."""
    try:
        func(*args, **kwargs)
    except Exception as err:  # noqa: BLE001
        if raised(err, exc_type):
            return
        raise AssertionError(f"expected {exc_type.__name__}, got {err}") from None
    raise AssertionError(f"expected {exc_type.__name__}, nothing was raised")


def fitted_order(dts: npt.ArrayLike, errors: npt.ArrayLike) -> float:
    """Return the slope of log(error) over log(dt): the observed order of convergence."""
    return float(np.polyfit(np.log(np.asarray(dts, float)), np.log(np.asarray(errors, float)), 1)[0])


def reference_run(method: str, problem: Problem, x: npt.ArrayLike, v: npt.ArrayLike, dt: float,
                  steps: int = 1) -> State:
    """Run mslab's own ``method`` from (x, v) for ``steps`` steps; return the final mslab State.

    Multistep methods are started with their own start-up step; the returned state
    carries their memory (Verlet: ``(x_prev, P)``, leapfrog: ``(v_half, a, P)``).
    """
    from mslab.integrators import get_method
    from mslab.state import State

    system = problem.system()
    integrator = get_method(method)
    state = integrator.start(system, State(np.array(x, dtype=float), np.array(v, dtype=float)), dt)
    for _ in range(steps):
        state = integrator.step(system, state, dt)
    return state


def swinging_spring(rng: np.random.Generator) -> tuple[Problem, np.ndarray, float]:
    """Draw a spring swinging sideways: ``(problem, v0, t_end)``.

    Nonlinear, so there is no closed form: an answer that imitates the exact flow of the
    oscillator plus an error of the tested order (implementing no method) cannot pass a
    test on it. Drawn at grading time (``np.random.default_rng()`` without a seed).
    """
    from mslab.grading.problems import problem

    prob = problem("oscillator", stiffness=float(rng.uniform(2.0, 6.0)),
                   displacement=float(rng.uniform(0.2, 0.5)), dim=2)
    v0 = np.zeros((2, 2))
    v0[1, 1] = rng.uniform(0.5, 1.0)
    return prob, v0, float(rng.uniform(1.5, 2.5))


def observed_order(run: Callable[[int], list], prob: Problem, v0: np.ndarray, t_end: float,
                   steps: tuple[int, ...] = (20, 40, 80), points: int = 4) -> float:
    """Return the observed order of ``run(n)``: the positions after each of its n steps to ``t_end``.

    The error of a run is the largest distance from mslab's RK4 at 4000 steps at ``points``
    checkpoints (``t_end * k / points``); the order is the slope over the step sizes.
    """
    from mslab.integrators import get_method
    from mslab.state import State

    system, rk4, fine = prob.system(), get_method("rk4"), 4000
    state, ref = rk4.start(system, State(prob.x0.copy(), np.array(v0, dtype=float)), t_end / fine), []
    for i in range(fine):
        state = rk4.step(system, state, t_end / fine)
        if (i + 1) % (fine // points) == 0:
            ref.append(state.x)
    errors = []
    for n in steps:
        xs = run(n)
        assert len(xs) == n, f"{len(xs)} positions for {n} steps"
        mine = [as_numbers(xs[(k + 1) * (n // points) - 1], prob.x0.shape, what="x") for k in range(points)]
        errors.append(float(np.max(np.linalg.norm(np.array(mine) - np.array(ref), axis=-1))))
    if not all(np.isfinite(errors)) or min(errors) <= 0.0:
        raise AssertionError(f"errors {errors}: not a convergent run")
    return fitted_order([t_end / n for n in steps], errors)


def step_order(step: Callable, rng: np.random.Generator, *args: Any) -> float:
    """Return the observed order of ``step(x, v, accel, dt, *args) -> (x, v)`` on a spring drawn from ``rng``.

    The spring swings sideways (:func:`swinging_spring`): nonlinear, no closed form to imitate.
    """
    prob, v0, t_end = swinging_spring(rng)

    def run(n: int) -> list:
        x, v, xs = prob.x0, v0, []
        for _ in range(n):
            x, v = step(x, v, prob, t_end / n, *args)
            xs.append(x)
        return xs

    return observed_order(run, prob, v0, t_end)


def check_known(outs: tuple, expected: tuple, mistakes: dict[str, tuple] | None = None,
                whats: tuple[str, ...] = ("result",), rtol: float = 1e-10, atol: float = 1e-12) -> None:
    """Each of ``outs`` must be close to its ``expected``; a known mistake's answer is named.

    The failure is one line (a named mistake's line leaves out the worst error, so that
    the hint fits the report's line). ``mistakes`` maps a one-line hint (e.g. "the two symplectic
    Eulers are swapped") to the answers that mistake produces; they are compared only once
    the answer is wrong, within the test's own tolerance.
    """
    for out, exp, what in zip(outs, expected, whats, strict=True):
        try:
            check_array(out, exp, rtol=rtol, atol=atol, what=what)
        except AssertionError:
            for hint, wrong in (mistakes or {}).items():
                if all(isinstance(a, np.ndarray) and a.shape == np.shape(b)
                       and np.allclose(a, b, rtol=max(rtol, 1e-8), atol=max(atol, 1e-10))
                       for a, b in zip(outs, wrong, strict=True)):
                    raise AssertionError(f"{what}: wrong values: likely mistake: {hint}") from None
            raise


def check_step(x: Any, v: Any, ref: State, mistakes: dict[str, State] | None = None,
               rtol: float = 1e-10, atol: float = 1e-12) -> None:
    """``(x, v)`` must be the step ``ref``; :func:`check_known` with the states of known mistakes."""
    check_known((x, v), (ref.x, ref.v), {h: (w.x, w.v) for h, w in (mistakes or {}).items()},
                ("x_new", "v_new"), rtol=rtol, atol=atol)
