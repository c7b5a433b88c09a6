"""Hostile values at the stepping session's public entry points (issue 37): only a TypeError or a
ValueError naming the argument escapes (or a run that honestly blows up), never an OverflowError,
a RecursionError or a numpy error from deep inside."""

from __future__ import annotations

import contextlib
import io

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mslab
from mslab.errors import InstabilityError, StepFailure

CHAIN = mslab.load_scene("chain").with_settings(dt=0.01, t_end=0.05)

HOSTILE = st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30), st.floats(allow_nan=True),
                    st.text(max_size=8), st.lists(st.integers(), max_size=3), st.just(np.float64("nan")),
                    st.just(np.int64(3)), st.complex_numbers(allow_nan=False, allow_infinity=False))
# steps: hostile, but a valid count stays small (a huge valid count is a long run, not an error)
STEPS = st.one_of(st.booleans(), st.integers(-10**30, 50), st.floats(allow_nan=True), st.text(max_size=8),
                  st.just(np.int64(3)), st.lists(st.integers(), max_size=3))


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(dt=HOSTILE, t_end=HOSTILE, save_every=HOSTILE, n=STEPS, t=st.one_of(st.none(), HOSTILE))
def test_hostile_values_raise_only_type_or_value_errors(dt, t_end, save_every, n, t):
    try:
        sim = mslab.Simulation(CHAIN, "euler", dt=dt, t_end=t_end, save_every=save_every,
                               backend="numpy", check_stability=False)
    except (TypeError, ValueError):
        return
    for call in ((lambda: sim.advance(n)), (lambda: sim.advance(t=t) if t is not None else None)):
        try:
            call()
        except (TypeError, ValueError, StepFailure, InstabilityError):  # a refusal, or a run that blew up
            pass


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(dt=HOSTILE, t_end=HOSTILE, save_every=HOSTILE)
def test_hostile_values_to_simulate_raise_only_type_or_value_errors(dt, t_end, save_every):
    short = isinstance(t_end, int | float) and not isinstance(t_end, bool) and abs(t_end) > 1
    try:
        mslab.simulate(CHAIN, "euler", dt=dt, t_end=0.05 if short else t_end, save_every=save_every,
                       backend="numpy", check_stability=False)
    except (TypeError, ValueError, StepFailure, InstabilityError):
        pass


# -- the command line's numeric options: the same checks (mslab.checks), one line, exit 2 ------------------
#: (command words before the option, option, attribute, what a value must be): "positive" a finite
#: number > 0, a number ">= m", or a whole number "count >= m"
CLI_OPTIONS = [(["run", "pendulum"], "--dt", "dt", "positive"),
               (["run", "pendulum"], "--t-end", "t_end", "positive"),
               (["run", "pendulum"], "--save-every", "save_every", "count >= 1"),
               (["validate", "pendulum"], "--dt", "dt", "positive"),
               (["compare", "pendulum"], "--dt", "dt", "positive"),
               (["compare", "pendulum"], "--t-end", "t_end", "positive"),
               (["precision", "oscillator"], "--dts", "dts", "positive"),
               (["precision", "oscillator"], "--t-end", "t_end", "positive"),
               (["precision", "oscillator"], "--rtols", "rtols", "positive"),
               (["precision", "oscillator"], "--repeats", "repeats", "count >= 1"),
               (["precision", "oscillator"], "--jobs", "jobs", "count >= 1"),
               (["precision", "oscillator"], "--budget", "budget", ">= 0"),
               (["grade", "sub"], "--timeout", "timeout", ">= 0.1"),
               (["grade", "sub"], "--memory", "memory", "count >= 64"),
               (["grade", "sub"], "--jobs", "jobs", "count >= 1")]

ODD = ["nan", "NaN", "-nan", "inf", "-inf", "1e999", "-1", "0", "-0", "0.0", "1.5", "1e3", "True", "", " ",
       "0x10", "1_000", "abc", "2", "64", "0.05", "1e-300"]
WORDS = st.one_of(st.sampled_from(ODD),
                  st.floats().map(repr), st.integers(-10**30, 10**30).map(str), st.text(max_size=8))


def accepted(value: object, rule: str) -> bool:
    """Whether ``value`` is what ``rule`` asks for: an exact int for a count, a finite float otherwise."""
    if rule.startswith("count"):
        return type(value) is int and value >= int(rule.split()[-1])
    if type(value) is not float or not np.isfinite(value):
        return False
    return value > 0 if rule == "positive" else value >= float(rule.split()[-1])


@settings(max_examples=300, deadline=None)
@given(case=st.sampled_from(CLI_OPTIONS), word=WORDS)
def test_hostile_option_values_are_refused_in_one_line_or_are_valid(case, word):
    """Fails on the old code: argparse's type=float let nan, inf and negatives through to the commands."""
    from mslab.cli import build_parser, main

    before, option, attribute, rule = case
    argv = [*before, f"{option}={word}"]
    with contextlib.redirect_stderr(io.StringIO()) as err:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as done:
            assert done.code == 2
            line = err.getvalue()
            assert line.startswith(f"mslab: error: {option}: ") and line.count("\n") == 1, line
            assert main(argv) == 2 and err.getvalue() == 2 * line  # main returns the code, same line
            return
    value = getattr(args, attribute)
    for one in value if isinstance(value, list) else [value]:
        assert accepted(one, rule), (argv, one)


def test_a_run_that_could_never_fit_in_memory_is_refused_before_any_array():
    """A huge t_end (1e12 s at dt = 0.01: 1e14 saved samples) failed with a MemoryError, or on an
    overcommitting OS was killed while filling its arrays; now one ValueError naming the arguments."""
    import pytest

    with pytest.raises(ValueError, match=r"t_end, save_every: .* GiB, more than this machine's"):
        mslab.Simulation(CHAIN, "euler", dt=0.01, t_end=1e12, backend="numpy", check_stability=False)
    with pytest.raises(ValueError, match="use a larger save_every"):
        mslab.simulate(CHAIN, "euler", dt=0.01, t_end=1e12, backend="numpy", check_stability=False)


def test_an_open_ended_session_that_could_never_hold_its_samples_is_refused_before_a_step():
    """An open-ended session given ``save_every`` grew its samples until the process was killed
    (``advance(10**13)`` saves 1e13 states); now one ValueError before any step, the session
    untouched and still usable."""
    import pytest

    sim = mslab.Simulation(CHAIN, "euler", dt=0.01, save_every=1, backend="numpy", check_stability=False)
    with pytest.raises(ValueError, match=r"advance, save_every: .* GiB, more than this machine.*fewer steps"):
        sim.advance(10**13)
    assert sim.step == 0 and sim.trajectory.x.shape[0] == 1
    sim.advance(10)
    assert sim.step == 10 and sim.trajectory.x.shape[0] == 11
    quiet = mslab.Simulation(CHAIN, "euler", dt=0.01, backend="numpy", check_stability=False)
    assert quiet._samples.refuse_beyond(10**13) is None  # the default saves only the start: nothing to refuse
