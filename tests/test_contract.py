"""The session's contract under careless and hostile use (issue 37, issue 41's backend item).

A session owns its data (edits of the scene, the method or what it hands out change nothing,
on both backends), refuses a second concurrent ``advance``, checks its arguments' types and
ranges with one TypeError/ValueError naming the argument, and decides its backend once,
when it starts. Summaries (``repr``) are one line, never the arrays.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

import mslab
from mslab import fast
from mslab.scenes import generators

pytestmark = pytest.mark.filterwarnings("ignore::mslab.StabilityWarning")

DT, STEPS = 2e-3, 40


def scene() -> mslab.Scene:
    return generators.chain(5, dim=2, stiffness=300.0, damping=0.3, gamma=0.2)


BACKENDS = ["numpy"] + ([] if fast.unsupported(scene().system, mslab.get_method("rk4")) else ["numba"])


@pytest.mark.parametrize("backend", BACKENDS)
def test_editing_everything_reachable_changes_nothing_in_the_run(backend):
    """Scene arrays, the springs' stiffness, sim.state's arrays: edited between advances, ignored."""
    clean = mslab.simulate(scene(), "rk4", dt=DT, t_end=STEPS * DT, backend=backend)
    sc = scene()
    sim = mslab.Simulation(sc, "rk4", dt=DT, t_end=STEPS * DT, backend=backend)
    sim.advance(STEPS // 2)
    springs = sc.springs().hooke_springs()
    springs.stiffness[:] *= 100.0  # the scene's own arrays, edited in place
    sc.system.mass[:] *= 3.0
    sc.state0.x[:] += 1.0
    state = sim.state
    state.x[:] = np.nan  # what the session handed out
    state.v[:] = 1e300
    sim.advance()
    out = sim.trajectory
    np.testing.assert_array_equal(out.x, clean.x)
    np.testing.assert_array_equal(out.v, clean.v)
    np.testing.assert_array_equal(out.energy.total, clean.energy.total)


@pytest.mark.parametrize("backend", BACKENDS)
def test_state_is_a_copy_on_every_backend(backend):
    sim = mslab.Simulation(scene(), "verlet", dt=DT, backend=backend)
    sim.advance(3)
    a, b = sim.state, sim.state
    assert a.x is not b.x and not np.shares_memory(a.x, b.x)
    a.x[:] = 0.0
    np.testing.assert_array_equal(b.x, sim.state.x)
    assert not np.array_equal(sim.state.x, a.x)


def test_a_second_concurrent_advance_is_refused_not_lost():
    """Thread A is held inside advance (its progress callback waits on an event); B is refused."""
    inside, release = threading.Event(), threading.Event()

    class Hold:
        def update(self, n: int) -> None:
            inside.set()
            assert release.wait(60)

    sim = mslab.Simulation(scene(), "rk4", dt=DT, backend="numpy")
    errors: list[BaseException] = []

    def first() -> None:
        try:
            sim.advance(10, progress=Hold())
        except BaseException as err:  # noqa: BLE001 - reported to the main thread
            errors.append(err)

    worker = threading.Thread(target=first)
    worker.start()
    assert inside.wait(60)
    with pytest.raises(RuntimeError, match="another thread"):
        sim.advance(5)
    release.set()
    worker.join(60)
    assert not errors and sim.step == 10
    sim.advance(5)
    assert sim.step == 15


@pytest.mark.parametrize(("kwargs", "error", "name"), [
    ({"dt": True}, TypeError, "dt"), ({"dt": "0.01"}, TypeError, "dt"),
    ({"dt": float("nan")}, ValueError, "dt"),
    ({"dt": -1.0}, ValueError, "dt"), ({"dt": float("inf")}, ValueError, "dt"),
    ({"save_every": 1.5}, TypeError, "save_every"), ({"save_every": "2"}, TypeError, "save_every"),
    ({"save_every": True}, TypeError, "save_every"), ({"save_every": 0}, ValueError, "save_every"),
    ({"t_end": "1"}, TypeError, "t_end"), ({"t_end": False}, TypeError, "t_end"),
    ({"blowup": -3.0}, ValueError, "blowup"), ({"energy_blowup": "big"}, TypeError, "energy_blowup"),
    ({"check_stability": 1}, TypeError, "check_stability"), ({"threads": 1.0}, TypeError, "threads"),
    ({"method": 3}, TypeError, "method"), ({"backend": 1}, TypeError, "backend"),
])
def test_bad_arguments_raise_one_error_naming_them(kwargs, error, name):
    with pytest.raises(error, match=name):
        mslab.Simulation(scene(), **{"method": "rk4", "dt": DT, **kwargs})
    with pytest.raises(error, match=name):
        mslab.simulate(scene(), **{"method": "rk4", "dt": DT, "t_end": STEPS * DT, **kwargs})


@pytest.mark.parametrize(("call", "error"), [
    ({"n": float("inf")}, TypeError), ({"n": 2.0}, TypeError), ({"n": True}, TypeError),
    ({"n": "3"}, TypeError),
    ({"n": -1}, ValueError), ({"t": float("inf")}, ValueError), ({"t": -0.1}, ValueError),
    ({"t": "0.1"}, TypeError), ({"t": float("nan")}, ValueError),
])
def test_bad_advance_arguments_raise_one_error(call, error):
    sim = mslab.Simulation(scene(), "rk4", dt=DT)
    with pytest.raises(error, match="^n |^t "):
        sim.advance(**call)
    assert sim.step == 0


def test_advance_t_zero_is_zero_steps_like_n_zero():
    sim = mslab.Simulation(scene(), "rk4", dt=DT)
    sim.advance(0)
    sim.advance(t=0.0)
    sim.advance(t=0)
    assert sim.step == 0


def test_backend_is_fixed_at_the_start_whatever_is_read_first():
    """Reading state/trajectory before the first advance, or a long first advance, changes nothing."""
    method = mslab.get_method("symplectic_euler")
    small = generators.chain(5, dim=2)
    first = mslab.Simulation(small, method, dt=1e-4, backend="auto", check_stability=False)
    decided = first.compiled
    _ = first.state, first.trajectory
    first.advance(50_000)  # a long first advance: the decision was made at the start (HORIZON)
    assert first.compiled == decided
    other = mslab.Simulation(small, method, dt=1e-4, backend="auto", check_stability=False)
    other.advance(50_000)
    np.testing.assert_array_equal(first.state.x, other.state.x)


def test_reprs_are_one_line_summaries():
    cloth = generators.cloth(40, 40, gravity=9.81)
    text = repr(cloth)
    assert "\n" not in text and len(text) < 300 and "1600 particles" in text
    tr = mslab.simulate(scene(), "rk4", dt=DT, t_end=STEPS * DT)
    text = repr(tr)
    assert "\n" not in text and len(text) < 300 and f"{STEPS + 1} samples" in text


def test_a_frame_loop_through_simulate_warns_once_naming_the_factor():
    """Each frame a new scene from the last state (one system): the 10th alike call warns, once."""
    import dataclasses
    import warnings

    from mslab.simulate import SHORT_CALLS, FrameLoopWarning

    sc = generators.chain(5, dim=2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(2 * SHORT_CALLS):
            tr = mslab.simulate(sc, "rk4", dt=1e-3, t_end=0.016)
            sc = dataclasses.replace(sc, state0=mslab.State(tr.x[-1], tr.v[-1]))
    frames = [w for w in caught if issubclass(w.category, FrameLoopWarning)]
    assert len(frames) == 1
    assert "Simulation" in str(frames[0].message) and "x its stepping time" in str(frames[0].message)


def test_a_sweep_over_dt_does_not_warn():
    import warnings

    from mslab.simulate import FrameLoopWarning

    sc = generators.chain(5, dim=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FrameLoopWarning)
        for k in range(1, 15):
            mslab.simulate(sc, "rk4", dt=1e-3 / k, t_end=0.016)
