"""Implicit Euler's Newton on a driven block at h = 0.08 (issue 41): where plain Newton fails, a
damped Newton (Armijo on |r|^2) finds the root; where plain Newton converges nothing changes.

The states: a 3 x 3 x 3 jelly block on its floor in a 20 m/s wind, velocities jostled by seeded
noise. Plain Newton (full steps, then halving at most to 1/64) fails on seeds 5 and 9; the
root the damped iteration returns is checked by evaluating the stage equation afresh.
"""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

import mslab
from mslab.errors import StepFailure
from mslab.integrators.newton import damped, solvers
from mslab.scenes.loader import SCENE_DIR
from mslab.scenes.validate import scene_from_doc

H = 0.08


def driven_block() -> mslab.Scene:
    text = (SCENE_DIR / "jelly_cube.toml").read_text().replace("n = [4, 4, 4]", "n = [3, 3, 3]")
    text = text.replace("[run]", "[wind]\nvelocity = [20.0, 0.0, 6.0]\ndrag = 0.5\n\n[run]")
    return scene_from_doc(tomllib.loads(text), "driven_block")


def jostled(scene: mslab.Scene, seed: int) -> np.ndarray:
    return scene.state0.v + 0.5 * np.random.default_rng(seed).normal(size=scene.state0.v.shape)


@pytest.mark.parametrize("seed", [5, 9])
def test_damped_newton_finds_the_root_plain_newton_misses(seed):
    scene = driven_block()
    system, x, v = scene.system, scene.state0.x, jostled(scene, seed)
    tol = 1e-10 * (1.0 + np.max(np.abs(v)))
    with pytest.raises(StepFailure, match="did not converge"):  # plain Newton alone (the old code)
        solvers._plain_stage(system, x, v, H, tol, 25, "auto", False, 4, "exact")
    X, V, a, _ = solvers.newton_stage(system, x, v, H, tol, 25)
    a_fresh, _ = system.rhs(x + H * V, V)  # the stage equation, evaluated anew
    assert np.array_equal(X, x + H * V)
    assert np.max(np.abs(V - v - H * a_fresh)) <= tol
    assert not np.allclose(V, v, atol=1e-3)  # a real step, not the start


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("seed", [5, 9])
def test_the_step_that_failed_now_runs(seed, backend):
    """One implicit Euler step of h = 0.08 from the jostled state: a ConvergenceError on the old code."""
    if backend == "numba":
        pytest.importorskip("numba")
    scene = driven_block()
    one = dataclasses.replace(scene, state0=mslab.State(scene.state0.x, jostled(scene, seed)))
    traj = mslab.simulate(one, "implicit_euler", dt=H, t_end=H, backend=backend, check_stability=False)
    assert traj.complete and traj.stats.n_iter > 25  # the failed attempt's work is counted too


def test_the_damped_newton_runs_only_after_plain_newton_failed(monkeypatch):
    """Where plain Newton converges the damped one is never called: those results are bitwise the old ones."""
    def never(*args, **kwargs):
        raise AssertionError("damped Newton called where plain Newton converged")

    monkeypatch.setattr(damped, "damped_stage", never)
    scene = driven_block()
    for seed in (0, 1, 2, 3):
        one = dataclasses.replace(scene, state0=mslab.State(scene.state0.x, jostled(scene, seed)))
        assert mslab.simulate(one, "implicit_euler", dt=H, t_end=H, backend="numpy",
                              check_stability=False).complete
    assert mslab.simulate(scene, "implicit_euler", dt=0.01, t_end=0.3, backend="numpy").complete
