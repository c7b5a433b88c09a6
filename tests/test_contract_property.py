"""Hostile values at the stepping session's public entry points (issue 37): only a TypeError or a
ValueError naming the argument escapes (or a run that honestly blows up), never an OverflowError,
a RecursionError or a numpy error from deep inside."""

from __future__ import annotations

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
