"""The fast mass-spring iterations in one compiled loop (mslab.integrators.families.local_global_loop).

Truth: the plain loop of LocalGlobal.step (local step, solve, update called from Python),
which the compiled loop must reproduce bit for bit (same spring terms in the same order for
every particle, same solves), for any split of the tree and any thread count.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from test_implicit_cloth import scaled_cloth

import mslab
from mslab.integrators.families import local_global, local_global_loop
from mslab.integrators.families.local_global import LocalGlobal
from mslab.integrators.newton import tree_solve

pytest.importorskip("cvxopt")


def steps(scene, method: LocalGlobal, n: int, compiled_loop: bool, bins: int, dt: float = 1 / 30):
    """``n`` steps, the tree split for ``bins`` threads: the states, the counters, the global step."""
    s = copy.deepcopy(scene.system)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tree_solve, "MIN_PARALLEL_ENTRIES", 0)  # split a small cloth too
        mp.setattr(tree_solve, "bins_for", lambda threads: bins)
        if not compiled_loop:
            mp.setattr(local_global, "tree_iterations", lambda g, system: None)
        state, out = scene.state0, []
        for _ in range(n):
            state = method.step(s, state, dt)
            out.append(state)
    return out, s.counters.snapshot(), local_global.global_step(s, dt)


@pytest.mark.parametrize("method", [LocalGlobal(), LocalGlobal(chebyshev=True), LocalGlobal(iterations=3),
                                    LocalGlobal(iterations=200, tol=1e-5),
                                    LocalGlobal(iterations=40, chebyshev=True, tol=1e-4)],
                         ids=["plain", "chebyshev", "three", "tol", "chebyshev-tol"])
@pytest.mark.parametrize("bins", [1, 2, 3])
def test_the_compiled_loop_gives_the_plain_loops_bits(method, bins):
    scene = scaled_cloth(20, drag_rate=1.0)  # pinned corners, gravity, drag
    fused, work_fused, g = steps(scene, method, 4, True, bins)
    assert g.loop is not None and g.factor.bins == bins
    plain, work_plain, g = steps(scene, method, 4, False, bins)
    assert g.loop is None and g.factor.bins == bins
    for a, b in zip(fused, plain, strict=True):
        assert np.array_equal(a.x, b.x) and np.array_equal(a.v, b.v)
        assert a.dissipated == b.dissipated
    assert work_fused == work_plain
    if method.tol is not None:  # stopped early, as the plain loop did
        assert work_fused["n_iter"] < 4 * method.iterations


def test_thread_count_does_not_change_the_bits():
    from mslab.jit import numba, threads

    scene = scaled_cloth(50, drag_rate=1.0)  # about 100k entries in L: split among the threads
    fms = mslab.get_method("fast_mass_spring")
    states = []
    for count in (1, numba().config.NUMBA_NUM_THREADS):
        s = copy.deepcopy(scene.system)
        with threads(count):
            states.append(fms.step(s, fms.step(s, scene.state0, 1 / 30), 1 / 30))
        assert local_global.global_step(s, 1 / 30).loop is not None
    assert np.array_equal(states[0].x, states[1].x)


def test_varying_forces_keep_the_plain_loop():
    scene = mslab.load_scene("cloth")  # 10 x 10: below DENSE_MAX unknowns, dense factors
    s = scene.system
    mslab.get_method("fast_mass_spring").step(s, scene.state0, 1 / 30)
    assert local_global.global_step(s, 1 / 30).loop is None


def test_a_change_stays_not_finite():
    worse = local_global_loop.worse
    assert worse(0.5, 0.25) == 0.5 and worse(0.25, 0.5) == 0.5
    assert np.isnan(worse(np.nan, 1.0)) and np.isnan(worse(1.0, np.inf)) and np.isnan(worse(np.nan, 0.0))


def test_process_pools_work_after_the_threads_ran():
    """GNU OpenMP is not fork-safe: mslab's pools start their workers from a fresh server process.

    The parent runs the compiled loop on its threads, then two workers do the same (one step
    of the 50 x 50 cloth each): forked from the parent, each would abort at its first
    parallel loop ("fork() called from a process already using GNU OpenMP").
    """
    from mslab.jit import numba
    from mslab.precision.runs import _run_tasks

    if numba().config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here: no OpenMP threads to fork from")
    scene = scaled_cloth(50, drag_rate=1.0)
    s = copy.deepcopy(scene.system)
    mslab.get_method("fast_mass_spring").step(s, scene.state0, 1 / 30)
    assert local_global.global_step(s, 1 / 30).factor.bins > 1  # the threads ran in this process
    tasks = [("mslab", scene, "fast_mass_spring", 1 / 30, 1 / 30, 2, None)] * 2
    pooled = _run_tasks(tasks, 2, None)
    alone = _run_tasks(tasks[:1], 1, None)
    assert all(np.array_equal(r["x"], alone[0]["x"]) for r in pooled)
