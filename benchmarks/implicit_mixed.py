"""Implicit Euler through a float32 supernodal factorisation (issue 38, item 4) against the two references.

Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/implicit_mixed.py [--quick] [--sizes 70 100]

On N x N cloths (the built-in cloth scaled, 1 kg, drag rate 1/s, dt = 1/60; as
``benchmarks/implicit_cloth.py``), every code steps from the same states (mslab's default
trajectory), each state timed ``repeats`` times with the codes interleaved; per-step medians are
summed. Codes:

* ``cholmod``: textbook Newton, numpy Jacobians, a fresh CHOLMOD factorisation (symbolic
  analysis and numeric) every iteration (``implicit_cloth.reference_cholmod_newton_step``);
* ``compiled_kept``: textbook Newton with mslab's compiled assembly of ``M - h^2 K - h D`` on its
  kept pattern, compiled forces, CHOLMOD's analysis kept (a fresh numeric factorisation every
  iteration), full Newton steps;
* ``double``: mslab's implicit Euler on the compiled path, ``factor_precision="double"``;
* ``mixed``: the same with float32 factors preconditioning CG (the default).

Also, on one Newton matrix of each cloth: the float32 factorisation against CHOLMOD's numeric
factorisation (kept analysis) and their solves, interleaved. Results in
``benchmarks/implicit_mixed.json`` (``runs``, by cloth size) with the machine and its load.
Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla

import mslab
from benchmarks.implicit_cloth import machine, reference_cholmod_newton_step, scaled_cloth, timed
from mslab.state import State
from mslab.threads import single_threaded_blas

HERE = Path(__file__).resolve().parent


def reference_compiled_kept_step(view, assembly, state, dt, rtol=1e-10, max_iter=25):
    """Textbook Newton: compiled forces and assembly, CHOLMOD numeric factorisation every iteration.

    ``assembly`` is mslab's compiled Newton matrix (``view.newton_assembly(dt, free)``): its
    pattern keeps CHOLMOD's symbolic analysis. Full Newton steps, the references' tolerance.
    """
    from mslab.integrators.newton.newton_matrix import cholmod_solve

    x0, v0 = state.x, state.v
    free = assembly.free
    mass = assembly.mass_free
    tol = rtol * (1.0 + np.abs(v0).max())
    v = v0.copy()
    for it in range(max_iter + 1):
        x = x0 + dt * v
        g = v - v0 - dt * view.acceleration(x, v)
        if np.abs(g).max() <= tol:
            return State(x, v), it
        A, _ = assembly.assemble(x, v)
        rhs = -(mass * g.ravel()[free])
        F = assembly.pattern.cholmod(assembly, A.data)
        dv = np.zeros(v.size)
        dv[free] = cholmod_solve(F, rhs) if F is not None else spla.spsolve(A.tocsc(), rhs)
        v = v + dv.reshape(v.shape)
    raise RuntimeError("reference Newton did not converge")


def steps_vs_references(n: int, steps: int, repeats: int = 3) -> dict:
    """Per-step medians of the four codes (module docstring) from the same states."""
    from mslab.fast.model import ForceModel
    from mslab.fast.newton import CompiledSystem

    scene = scaled_cloth(n)
    system, dt = scene.system, 1 / 60
    view = CompiledSystem(system, ForceModel(system))
    view.warm()
    mixed = mslab.ImplicitRK([[1]], [1], name="ie_mixed", order=1)
    double = mslab.ImplicitRK([[1]], [1], name="ie_double", order=1, factor_precision="double")
    assembly = view.newton_assembly(dt, np.repeat(~system.pinned, system.dim))
    state = scene.state0
    for _ in range(2):  # patterns, analyses, first factorisations, compilation
        double.step(view, state, dt)
        reference_compiled_kept_step(view, assembly, state, dt)
        state = mixed.step(view, state, dt)
    runs = {"cholmod": lambda s: reference_cholmod_newton_step(system, s, dt)[0],
            "compiled_kept": lambda s: reference_compiled_kept_step(view, assembly, s, dt)[0],
            "double": lambda s: double.step(view, s, dt), "mixed": lambda s: mixed.step(view, s, dt)}
    times = {k: [] for k in runs}
    diff = {k: 0.0 for k in runs}
    work = {"double": {}, "mixed": {}}
    for _ in range(steps):
        per = {k: [] for k in runs}
        out = {}
        for rep in range(repeats):
            for k, f in runs.items():
                before = system.counters.snapshot()
                t, out[k] = timed(f, state)
                if k in work and rep == 0:
                    work[k] = {w: work[k].get(w, 0) + c for w, c in system.counters.since(before).items()}
                per[k].append(t)
        step = float(np.abs(out["cholmod"].x - state.x).max())
        for k in runs:
            times[k].append(float(np.median(per[k])))
            diff[k] = max(diff[k], float(np.abs(out[k].x - out["cholmod"].x).max()) / step)
        state = out["mixed"]
    tot = {k: float(np.sum(v)) for k, v in times.items()}
    per_step = np.array([times[k] for k in runs])
    return {"n": n, "unknowns": 3 * int(np.count_nonzero(~system.pinned)), "steps": steps, "repeats": repeats,
            "s_per_step": {k: v / steps for k, v in tot.items()},
            "speedup_mixed_vs_fresh_cholmod": tot["cholmod"] / tot["mixed"],
            "speedup_mixed_vs_compiled_kept": tot["compiled_kept"] / tot["mixed"],
            "speedup_double_vs_fresh_cholmod": tot["cholmod"] / tot["double"],
            "speedup_double_vs_compiled_kept": tot["compiled_kept"] / tot["double"],
            "speedup_mixed_vs_double": tot["double"] / tot["mixed"],
            "per_step_range_mixed_vs_fresh_cholmod": [float(np.min(per_step[0] / per_step[3])),
                                                      float(np.max(per_step[0] / per_step[3]))],
            "per_step_range_mixed_vs_compiled_kept": [float(np.min(per_step[1] / per_step[3])),
                                                      float(np.max(per_step[1] / per_step[3]))],
            "max_position_difference_from_fresh_cholmod_relative_to_step": diff,
            "work_per_step": {k: {w: c / steps for w, c in v.items()} for k, v in work.items()}}


def factorisations(n: int, repeats: int = 9) -> dict:
    """The float32 factorisation and solve against CHOLMOD's (kept analysis) on one Newton matrix."""
    from mslab.integrators.newton import linear, mixed
    from mslab.integrators.newton.factor import Factor
    from mslab.system import Counters

    scene = scaled_cloth(n)
    system, dt = scene.system, 1 / 60
    state = mslab.ImplicitRK([[1]], [1], name="ie", order=1).step(system, scene.state0, dt)
    solver = linear.StageSolver(system, dt, "reuse")
    A = solver._assemble((state.x + dt * state.v, state.v), None)
    counters = Counters()
    start = time.perf_counter()
    analysis = mixed.analysis_of(solver.pattern, A, system.dim)
    analysis_s = time.perf_counter() - start
    f32 = mixed.mixed_factor(A, counters, solver.pattern, system.dim)
    f64 = Factor(A, counters, pattern=solver.pattern, symmetric=True)
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    t = {"factor32": [], "factor64": [], "solve32": [], "solve64": []}
    for _ in range(repeats):
        t["factor32"].append(timed(mixed.mixed_factor, A, counters, solver.pattern, system.dim)[0])
        seconds, f64 = timed(Factor, A, counters, False, solver.pattern, True)
        t["factor64"].append(seconds)
        t["solve32"].append(timed(f32.solve, b)[0])
        t["solve64"].append(timed(f64.solve, b)[0])
    x = f32.solve(b)
    return {"n": n, "unknowns": A.shape[0], "analysis_s": analysis_s, "flops": analysis.flops,
            "L_entries_float32": analysis.l_size, "supernodes": int(analysis.sn.shape[0]),
            "ms": {k: 1e3 * float(np.median(v)) for k, v in t.items()},
            "factor_ratio_64_over_32": float(np.median(np.array(t["factor64"]) / np.array(t["factor32"]))),
            "solve_ratio_64_over_32": float(np.median(np.array(t["solve64"]) / np.array(t["solve32"]))),
            "one_application_relative_residual": float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))}


@single_threaded_blas
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 30 x 30 cloth, 2 steps")
    parser.add_argument("--sizes", type=int, nargs="*", default=[70])
    parser.add_argument("--steps", type=int, default=6)
    args = parser.parse_args()
    sizes = [30] if args.quick else args.sizes
    out = {"machine_start": machine(), "factorisations": [], "steps": []}
    for n in sizes:
        out["factorisations"].append(factorisations(n))
        print(json.dumps(out["factorisations"][-1], indent=1), flush=True)
        out["steps"].append(steps_vs_references(n, 2 if args.quick else args.steps))
        print(json.dumps(out["steps"][-1], indent=1), flush=True)
    out["machine_end"] = machine()
    if not args.quick:  # one entry per cloth size; a run replaces the entries of its sizes only
        path = HERE / "implicit_mixed.json"
        kept = json.loads(path.read_text()).get("runs", {}) if path.exists() else {}
        kept.update({str(n): out for n in sizes})
        path.write_text(json.dumps({"runs": kept}, indent=1) + "\n")


if __name__ == "__main__":
    main()
