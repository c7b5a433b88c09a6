"""The compiled loop loads from numba's cache without numba's compiler set-up (issue 38, item 0).

Loading cached machine code needs numba's runtime only; numba's full target set-up (every
implementation it could compile, numpy's linear algebra with scipy's) cost 0.4-0.8 s of
each fresh process. Checked in fresh processes, by what they import, not by a clock.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import mslab
from mslab import fast

ROOT = Path(__file__).resolve().parent.parent

FRESH = """
import json, sys
import numpy as np
import mslab
from mslab import fast
scene = mslab.load_scene("chain")
method = mslab.get_method("rk4")
runner = fast.stepper(scene.system, method, "numba")
loop = runner.model.module.run_explicit_rk
traj = mslab.simulate(scene, method, t_end=0.05, backend="numba")
print(json.dumps({"linalg": "numba.np.linalg" in sys.modules, "hits": sum(loop.stats.cache_hits.values()),
                  "misses": sum(loop.stats.cache_misses.values()), "x": traj.x[-1].tolist(),
                  "auto": [fast.worth_compiling(scene.system, method, n) for n in (10, 10**3, 10**6)]}))
"""


def _fresh() -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("MSLAB_BACKEND", None)
    out = subprocess.run([sys.executable, "-c", FRESH], env=env, capture_output=True, text=True, check=True,
                         timeout=600)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_cached_loop_loads_without_the_compiler_set_up_and_steps_the_same():
    scene = mslab.load_scene("chain")
    method = mslab.get_method("rk4")
    fast.stepper(scene.system, method, "numba")  # compiled and cached here if it was not yet
    here = mslab.simulate(scene, method, t_end=0.05, backend="numba")
    doc = _fresh()
    assert doc["hits"] >= 1 and doc["misses"] == 0  # loaded from the cache, not compiled (the session
    # steps its own copy of the scene: a second signature of the same cached code may load too)
    assert not doc["linalg"]  # numba's numpy/linear-algebra implementations were not set up
    assert doc["x"] == here.x[-1].tolist()  # bitwise the steps of this (compiling) process


def test_auto_takes_the_same_backend_in_a_fresh_process_and_after_other_runs():
    scene = mslab.load_scene("chain")
    method = mslab.get_method("rk4")
    mslab.simulate(scene, "leapfrog", t_end=0.05, backend="numba")
    mslab.simulate(scene, method, t_end=0.05, backend="numpy")
    after = [fast.worth_compiling(scene.system, method, n) for n in (10, 10**3, 10**6)]
    assert _fresh()["auto"] == after
    assert after[0] is False and after[2] is True


def test_the_cost_model_counts_the_force_evaluations_a_step_makes():
    """``evaluations_per_step`` is what the system counts (a kick of damped forces is a Runge-Kutta step).

    The old model took ``n_stages`` (1 for velocity Verlet, 3 for Forest-Ruth), 4x too few on
    the damped rope: fails on the old code (no such method).
    """
    scene = mslab.load_scene("hanging_rope")  # damped: its kicks step velocity-dependent forces
    for name in ("velocity_verlet", "forest_ruth", "rk4", "symplectic_euler", "leapfrog"):
        method = mslab.get_method(name)
        traj = mslab.simulate(scene, method, t_end=0.02, backend="numpy", check_stability=False)
        steps = round(0.02 / scene.settings.dt)
        counted = (traj.stats.n_force - method.n_start) / steps
        assert abs(counted - method.evaluations_per_step(scene.system)) <= 1 / steps, name


def test_auto_compiles_the_runs_that_take_a_fifth_of_a_second_in_numpy():
    """Issue 38 item 0: a lone default call of >= 0.2 s steps compiled (numpy is 40-170x slower once
    the compiled loop is loaded). Runs measured at 0.3-0.6 s in numpy on an idle machine
    (benchmarks/lone_call.py) that the old rule kept in numpy; a few steps stay numpy.
    """
    from mslab.scenes import generators

    chain, rk4 = mslab.load_scene("chain"), mslab.get_method("rk4")
    assert fast.worth_compiling(chain.system, rk4, 1000)  # the chain's second, rk4 at t_end 1
    jelly = mslab.load_scene("jelly_cube")
    assert fast.worth_compiling(jelly.system, mslab.get_method("symplectic_euler"), 1500)
    assert fast.worth_compiling(generators.chain(20, dim=3).system, rk4, 1600)  # rk4 at a 1e-6 error
    assert not fast.worth_compiling(chain.system, rk4, 20)
