"""``dtype="float32"``: the compiled loop in single precision (issue 38, item 2).

Error model (docs/precision.md, "float32"): a stable one-step method rounds every stored
coordinate once per step (relative ``eps32 / 2``), its increments a few times (relative to
``h |v|`` and ``h^2 |a|``, far below ``|x|``) and forms the spring forces in float32; a
stable step carries an error on without
growth, so after ``N`` steps ``max |x32 - x64| <= N eps32 X`` (``X`` the largest coordinate of
the run), and the ledger ``K + U + D`` moves by at most ``N eps32`` of the energy scale. Verlet
is left out of that bound (its velocity is a difference of rounded positions over ``h``:
docs/precision.md), and so are contact scenes (their motion amplifies any perturbation).
"""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np
import pytest

import mslab
from mslab.effects import Springs
from mslab.errors import InstabilityError
from mslab.ledger import initial_energy_scale
from mslab.scenes import generators
from mslab.stability import predicted_stable_dt
from mslab.system import System
from tests.test_fast import _Kick  # an effect without a kernel

pytestmark = [pytest.mark.filterwarnings("ignore::mslab.StabilityWarning")]

EPS32 = float(np.finfo(np.float32).eps)


def frame_cloth(n: int):
    """The frame loop's cloth (benchmarks/frame_loop.py): stable at dt = 1/960, rows of springs."""
    return generators.cloth(n, n, size=0.02 * (n - 1), mass=0.25 * n * n, structural=1000.0, shear=1000.0,
                            bend=1000.0, damping=10.0, gravity=9.81)


def scene_of(name: str):
    return frame_cloth(int(name[5:])) if name.startswith("cloth") else mslab.load_scene(name)


def run(name: str, method: str, steps: int, dt: float | None = None, **options):
    sim = mslab.Simulation(scene_of(name), method, dt, backend="numba", check_stability=False, **options)
    sim.advance(steps)
    return sim


@pytest.mark.parametrize("name, method, steps, dt", [
    ("chain", "symplectic_euler", 1000, None), ("chain", "leapfrog", 1000, None),
    ("chain", "rk4", 1000, None),
    ("pendulum", "rk4", 4000, None), ("hanging_rope", "rk4", 3000, None),
    ("cloth64", "symplectic_euler", 480, 1 / 960)])
def test_float32_agrees_with_float64_within_the_roundoff_model(name, method, steps, dt):
    s64, s32 = run(name, method, steps, dt), run(name, method, steps, dt, dtype="float32")
    x64, x32 = s64.state.x, s32.state.x
    assert x32.dtype == np.float64  # what a session hands out stays float64
    size = float(np.abs(s64.trajectory.x).max())
    gap = float(np.abs(x32 - x64).max())
    assert gap <= steps * EPS32 * size  # the model's bound
    assert gap > 1e-9 * size  # float32 really ran (float64 round-off is 1e-13 here)
    scale = initial_energy_scale(scene_of(name))
    e64, e32 = s64.trajectory.energy.total, s32.trajectory.energy.total
    assert float(np.abs(e32 - e64).max()) <= steps * EPS32 * scale


def test_float32_is_refused_where_there_is_no_float32_loop(monkeypatch):
    chain = generators.chain(4)
    with pytest.raises(ValueError, match="dtype 'float32'.*backend 'numpy'"):
        mslab.simulate(chain, "rk4", dt=1e-2, t_end=0.1, backend="numpy", dtype="float32")
    monkeypatch.setenv("MSLAB_BACKEND", "numpy")
    with pytest.raises(ValueError, match="dtype 'float32'.*backend 'numpy'"):
        mslab.Simulation(chain, "rk4", dt=1e-2, dtype=np.float32)
    monkeypatch.delenv("MSLAB_BACKEND")
    with pytest.raises(ValueError, match="dtype 'float32'.*implicit"):
        mslab.simulate(chain, "implicit_euler", dt=1e-2, t_end=0.1, dtype="float32")
    with pytest.raises(ValueError, match="dtype 'float32'.*no compiled stepping loop"):
        mslab.simulate(chain, "fast_mass_spring", dt=1e-2, t_end=0.1, dtype="float32")
    system = System(chain.system.mass, chain.system.pinned, chain.system.effects + (_Kick(),), chain.dim)
    with pytest.raises(ValueError, match=r"dtype 'float32'.*\['kick'\] have no compiled kernel"):
        mslab.simulate(dataclasses.replace(chain, system=system), "rk4", dt=1e-2, t_end=0.1, dtype="float32")
    for bad in ("float16", "double32", 3, True):
        with pytest.raises(ValueError, match="dtype must be one of float64, float32"):
            mslab.simulate(chain, "rk4", dt=1e-2, t_end=0.1, dtype=bad)


def test_float32_auto_steps_compiled_even_a_short_run():
    sim = mslab.Simulation(generators.chain(4), "rk4", dt=1e-2, t_end=0.1, dtype="float32")
    assert sim.compiled
    assert not mslab.Simulation(generators.chain(4), "rk4", dt=1e-2, t_end=0.1).compiled


def test_float32_is_the_same_run_in_chunks_and_on_any_thread_count():
    one = run("cloth180", "symplectic_euler", 48, 1 / 960, dtype="float32", threads=1)
    two = mslab.Simulation(frame_cloth(180), "symplectic_euler", 1 / 960, backend="numba",
                           check_stability=False, dtype="float32", threads=2)
    for _ in range(3):
        two.advance(16)
    springs = next(e for e in two.system.effects if isinstance(e, Springs))
    assert springs.kernel_params()[9].size > 2  # phases of batches on both threads
    np.testing.assert_array_equal(one.state.x, two.state.x)
    np.testing.assert_array_equal(one.state.v, two.state.v)
    assert one.state.dissipated == two.state.dissipated


@pytest.mark.parametrize("name, method, factor", [
    ("chain", "symplectic_euler", 1.2), ("hanging_rope", "rk4", 1.1), ("jelly_cube", "symplectic_euler", 1.5),
    ("pendulum", "verlet", 1.3)])
def test_the_ledger_check_stops_an_unstable_float32_run_where_float64_stops(name, method, factor):
    scene = mslab.load_scene(name)
    dt = predicted_stable_dt(scene, method) * factor
    steps = []
    for dtype in ("float64", "float32"):
        with pytest.raises(InstabilityError, match="energy ledger") as err:
            mslab.simulate(scene, method, dt=dt, t_end=5000 * dt, backend="numba", dtype=dtype)
        steps.append(err.value.step)
    assert steps[0] == steps[1]


#: sha256 (first 16 hex digits) of the positions main's compiled loop reached (commit cb896a4)
MAIN = {("cloth64", "symplectic_euler", 64, 1 / 960): "1aded277ee95fdd5",
        ("cloth64", "rk4", 16, 1 / 960): "722cc9c100898ca8",
        ("chain", "verlet", 300, None): "c9767584691ab39c",
        ("hanging_rope", "rk4", 300, None): "8efd7366317e2f1a",
        ("jelly_cube", "rk4", 100, None): "99eb299bf885e32c"}


@pytest.mark.parametrize("case", list(MAIN))
def test_float64_is_bitwise_the_loop_of_before(case):
    name, method, steps, dt = case
    x = run(name, method, steps, dt, dtype="float64", threads=1).state.x
    assert hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest()[:16] == MAIN[case]
