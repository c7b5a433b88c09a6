"""Hidden tests of exercise 10 (graded, not released)."""

import math

import numpy as np
import pytest

from mslab.grading.checks import as_count
from mslab.precision import convergence
from mslab.scenes.generators import oscillator

MODULE = "cheapest_method"


def reference_choice(runs, target, t_end):
    best = None
    for name, run in runs.items():
        p, log_c = np.polyfit(np.log(run["dts"]), np.log(run["errors"]), 1)
        h = (target / math.exp(log_c)) ** (1.0 / p)
        n_steps = math.ceil(t_end / h)
        n_force = n_steps * run["evals_per_step"] + run["start_evals"]
        if best is None or n_force < best[2]:
            best = (name, n_steps, n_force)
    return best


@pytest.mark.points(2)
def test_choice_from_runs_measured_by_the_library_reaches_the_target(student):
    scene = oscillator(stiffness=1.0, mass=1.0, displacement=0.1)
    t_end = 1.25 * 2 * np.pi
    methods = {"symplectic_euler": (1, 0), "heun": (2, 0), "rk4": (4, 0), "leapfrog": (1, 1)}
    conv = convergence(scene, list(methods), [t_end / n for n in (50, 100, 200)], t_end=t_end)
    runs = {m: {"dts": [r["dt"] for r in conv.records if r["method"] == m],
                "errors": [r["error"] for r in conv.records if r["method"] == m],
                "evals_per_step": e, "start_evals": s} for m, (e, s) in methods.items()}
    for target in (1e-3, 1e-7):
        expected = reference_choice(runs, target, t_end)
        got = student.cheapest(runs, target, t_end)
        assert (got[0], as_count(got[1], "n_steps"), as_count(got[2], "n_force")) == expected, \
            f"target {target:g}: {got}, expected {expected}"
    # the tight target's choice, run at its predicted steps, reaches the target (within the model's factor 2)
    name, n_steps, _ = expected
    check = convergence(scene, [name], [t_end / n_steps], t_end=t_end)
    error = check.records[0]["error"]
    assert error < 2e-7, f"{name} at {n_steps} steps: error {error:.2e}"


@pytest.mark.points(1)
def test_the_start_up_evaluation_decides_a_tie(student):
    # two methods with the same error model and cost per step: the one without a start-up evaluation wins
    dts = [0.1, 0.05]
    same = {"dts": dts, "errors": [0.3 * h**2 for h in dts], "evals_per_step": 1}
    runs = {"leapfrog": dict(same, start_evals=1), "symplectic_euler_2": dict(same, start_evals=0)}
    name, n_steps, n_force = student.cheapest(runs, 1e-4, 2.0)
    assert name == "symplectic_euler_2", f"chose {name!r}: leapfrog pays one more evaluation to start"
    assert as_count(n_force, "n_force") == as_count(n_steps, "n_steps") == 110, \
        f"(n_steps, n_force) = {(n_steps, n_force)}, expected (110, 110)"


@pytest.mark.points(2)
def test_a_table_drawn_at_grading(student):
    rng = np.random.default_rng()
    t_end = float(rng.uniform(0.5, 5.0))
    runs = {}
    for k in range(int(rng.integers(3, 6))):
        p = int(rng.integers(1, 5))
        C = float(10 ** rng.uniform(-2, 1))
        dts = [0.1, 0.05, 0.025]
        runs[f"method_{k}"] = {"dts": dts, "errors": [C * h**p * (1 + 0.05 * rng.normal()) for h in dts],
                               "evals_per_step": int(rng.integers(1, 5)),
                               "start_evals": int(rng.integers(0, 2))}
    target = float(10 ** rng.uniform(-7, -2))
    expected = reference_choice(runs, target, t_end)
    got = student.cheapest(runs, target, t_end)
    assert (got[0], as_count(got[1], "n_steps"), as_count(got[2], "n_force")) == expected, \
        f"target {target:.2e}: {got}, expected {expected}"
