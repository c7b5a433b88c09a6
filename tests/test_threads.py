"""Multi-core spring loops: conflict-free batches, the numpy reference, bitwise equal on any thread count."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mslab
from mslab import fast
from mslab.cli import main
from mslab.effects import Springs
from mslab.effects.spring_batches import (
    MAX_BLOCKS,
    MIN_SPRINGS_PARALLEL,
    MIN_SPRINGS_PER_BATCH,
    batches,
    block_count,
)
from mslab.jit import numba, thread_count
from mslab.scenes import generators

pytestmark = pytest.mark.filterwarnings("ignore::mslab.StabilityWarning")


def conflict_free(i: np.ndarray, j: np.ndarray, ranges: np.ndarray, phases: np.ndarray) -> bool:
    """No particle is touched by two batches of one phase (a plain set check, independent of the code)."""
    for p in range(len(phases) - 1):
        owner: dict[int, int] = {}
        for r in range(phases[p], phases[p + 1]):
            batch = slice(ranges[r], ranges[r + 1])
            for particle in set(i[batch].tolist()) | set(j[batch].tolist()):
                if owner.setdefault(particle, r) != r:
                    return False
    return True


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 400), m=st.integers(0, 1500), span=st.integers(1, 400),
       seed=st.integers(0, 2**32 - 1))
def test_batches_are_a_conflict_free_partition(n, m, span, seed):
    """Any springs (near or far apart): every spring in exactly one batch, no conflict within a phase."""
    rng = np.random.default_rng(seed)
    i = rng.integers(0, n, m)
    j = (i + rng.integers(1, min(span, n - 1) + 1, m)) % n
    order, ranges, phases = batches(i, j, n, min_parallel=64, per_batch=16)
    assert np.array_equal(np.sort(order), np.arange(m))
    assert ranges[0] == 0 and ranges[-1] == m and np.all(np.diff(ranges) >= 0)
    assert phases[0] == 0 and phases[-1] == len(ranges) - 1
    assert conflict_free(i[order], j[order], ranges, phases)
    # within a batch the scene's order is kept (stable)
    for r in range(len(ranges) - 1):
        assert np.all(np.diff(order[ranges[r]:ranges[r + 1]]) > 0)


def test_a_cloth_needs_no_serial_springs():
    """Row-numbered cloth: every spring lies in adjacent blocks, so the serial last phase is empty."""
    scene = generators.cloth(170, 170)
    springs = next(e for e in scene.system.effects if isinstance(e, Springs))
    order, ranges, phases = batches(springs.i, springs.j, scene.system.n_particles)
    blocks = block_count(scene.system.n_particles, len(springs.i))
    assert blocks == min(MAX_BLOCKS, len(springs.i) // MIN_SPRINGS_PER_BATCH) > 1
    assert ranges[phases[-2]] == ranges[-1]  # the serial phase has no spring
    assert conflict_free(springs.i[order], springs.j[order], ranges, phases)


def cloth_state(dim: int, damped: bool, seed: int = 0):
    """A 170 x 170 cloth's springs (damped or not; in 2D without gravity), moved at random."""
    scene = generators.cloth(170, 170)
    system = scene.system
    springs = next(e for e in system.effects if isinstance(e, Springs))
    new = Springs(springs.springs, springs.stiffness, springs.rest_length,
                  np.full(len(springs.i), 0.3 if damped else 0.0), system.n_particles)
    effects = [new if e is springs else e for e in system.effects] if dim == 3 else [new]
    system = mslab.System(system.mass, system.pinned, effects, dim)
    rng = np.random.default_rng(seed)
    x0 = scene.state0.x[:, :dim]
    x = x0 + 1e-2 * rng.normal(size=x0.shape)
    v = rng.normal(size=x0.shape)
    return system, x, v


@pytest.mark.parametrize("dim, damped", [(3, False), (3, True), (2, True)])
def test_batched_kernel_equals_numpy_reference(dim, damped):
    """The compiled, batched sum equals System.force (another summation order: round-off only)."""
    system, x, v = cloth_state(dim, damped)
    springs = next(e for e in system.effects if isinstance(e, Springs))
    assert len(springs.kernel_params()[8]) > 3  # several batches: the parallel path runs
    f, power = fast.ForceModel(system).force(x, v)
    ref = system.force(x, v)
    # each entry sums at most 12 pair forces of size |k d|: error about 12 eps of that size
    scale = float(np.max(springs.stiffness)) * float(np.max(np.abs(x)))
    assert np.max(np.abs(f - ref)) <= 64 * np.finfo(float).eps * scale
    ref_power = springs.power(x, v)
    assert abs(power - ref_power) <= 1e-12 * max(1.0, abs(ref_power))


def two_threads() -> bool:
    return numba().config.NUMBA_NUM_THREADS >= 2


@pytest.mark.skipif("not two_threads()", reason="numba sees one core (NUMBA_NUM_THREADS < 2)")
@pytest.mark.parametrize("dim, damped", [(3, False), (3, True), (2, True)])
def test_forces_bitwise_equal_on_one_and_two_threads(dim, damped):
    system, x, v = cloth_state(dim, damped, seed=1)
    model = fast.ForceModel(system)
    nb = numba()
    out = {}
    for n in (1, 2, 1):
        nb.set_num_threads(n)
        out.setdefault(n, []).append(model.force(x, v))
    nb.set_num_threads(nb.config.NUMBA_NUM_THREADS)
    (f1, p1), (f2, p2), (f1b, p1b) = out[1][0], out[2][0], out[1][1]
    assert np.array_equal(f1, f2) and p1 == p2
    assert np.array_equal(f1, f1b) and p1 == p1b


@pytest.mark.skipif("not two_threads()", reason="numba sees one core (NUMBA_NUM_THREADS < 2)")
@pytest.mark.parametrize("method", ["symplectic_euler", "rk4", "verlet"])
def test_runs_bitwise_equal_for_any_thread_count(method):
    """A damped cloth stepped on 1 and 2 threads: the same positions, velocities and ledger, bit for bit."""
    scene = generators.cloth(170, 170)
    scene = dataclasses.replace(scene, settings=dataclasses.replace(scene.settings, dt=1e-4))
    a, b = (mslab.simulate(scene, method, t_end=0.002, save_every=5, backend="numba", threads=n)
            for n in (1, 2))
    assert np.array_equal(a.x, b.x) and np.array_equal(a.v, b.v)
    assert np.array_equal(a.energy.total, b.energy.total)
    assert a.stats.n_force == b.stats.n_force


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_thread_count_is_checked(bad):
    with pytest.raises(ValueError, match="threads"):
        thread_count(bad)


def test_bad_mslab_threads_is_one_line_on_the_command_line(tmp_path, monkeypatch, capsys):
    """``$MSLAB_THREADS`` is checked before any work: one line, exit 2, nothing written."""
    monkeypatch.setenv("MSLAB_THREADS", "many")
    monkeypatch.chdir(tmp_path)
    assert main(["run", "pendulum", "--t-end", "0.01"]) == 2
    out, err = capsys.readouterr()
    assert err.splitlines() == ["mslab: error: MSLAB_THREADS: expected a whole number >= 1, got 'many'"]
    assert out == "" and list(tmp_path.iterdir()) == []


def test_small_scenes_stay_one_batch():
    """Below MIN_SPRINGS_PARALLEL springs, one batch: no parallel loop (its start costs more)."""
    scene = generators.cloth(64, 64)
    springs = next(e for e in scene.system.effects if isinstance(e, Springs))
    order, ranges, phases = batches(springs.i, springs.j, scene.system.n_particles)
    assert len(springs.i) < MIN_SPRINGS_PARALLEL
    assert np.array_equal(order, np.arange(len(springs.i))) and ranges.tolist() == [0, len(springs.i)]


@pytest.mark.parametrize("preset, expected", [(None, "PASSIVE"), ("ACTIVE", "ACTIVE")])
def test_openmp_threads_sleep_unless_the_user_chose(preset, expected):
    """Loading numba through mslab sets OMP_WAIT_POLICY=PASSIVE, never over the user's own choice."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    if preset is not None:
        env["OMP_WAIT_POLICY"] = preset
    code = "import os; from mslab.jit import numba; numba(); print(os.environ['OMP_WAIT_POLICY'])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == expected


def test_springs_of_the_plain_loop_count_double_toward_threads():
    """The same 100k springs: in rows (all runs, half the time each) one batch; shuffled, batches."""
    scene = generators.cloth(130, 130)
    springs = next(e for e in scene.system.effects if isinstance(e, Springs))
    m = len(springs.i)
    assert MIN_SPRINGS_PARALLEL <= m < 2 * MIN_SPRINGS_PARALLEL
    order, ranges, phases = batches(springs.i, springs.j, scene.system.n_particles)
    assert ranges.tolist() == [0, m]  # every spring in a run: work m / 2, below the threshold
    shuffled = np.random.default_rng(0).permutation(m)
    _, ranges, _ = batches(springs.i[shuffled], springs.j[shuffled], scene.system.n_particles)
    assert len(ranges) - 2 == block_count(scene.system.n_particles, m) > 1  # blocks, then the far springs
