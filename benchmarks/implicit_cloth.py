"""Implicit methods at cloth scale (issue 12): mslab against references written here.

Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/implicit_cloth.py [--quick]

Measures, in one run with the machine recorded (times are medians or sums of interleaved
repeats, ratios compare timings of this run):

1. implicit Euler step on N x N cloths (N = 70, 100; dt = 1/60): mslab's Newton (kept
   factorisations, symmetric free-dof matrix; with numpy evaluations and on the compiled
   view of ``backend="numba"``) against a textbook Newton written here that
   assembles ``I - h M^-1 (h K + D)`` and calls ``scipy.sparse.linalg.spsolve`` (a fresh
   SuperLU factorisation) every iteration, same tolerance; both step from the same states;
2. a fast_mass_spring frame (h = 1/30, 10 iterations) on an 81 x 81 cloth against the same
   iterations in plain numpy + SuperLU (vectorised local step, ``splu`` of the same matrix),
   and against mslab's implicit Euler step on the same cloth;
3. how both scale with the number of particles (log-log slope);
4. how far 10 iterations are from implicit Euler's step, frame by frame.

The cloth is the built-in scene scaled to N x N with the same 1 kg and a drag rate of 1/s
(``gamma = m_particle / s``, see ``mslab/scenes/cloth.toml``). Nothing here is a test.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import scipy
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import mslab
from mslab.scenes.loader import scene_path
from mslab.scenes.toml_read import read_scene_file
from mslab.scenes.validate import scene_from_doc
from mslab.state import State
from mslab.threads import single_threaded_blas

HERE = Path(__file__).resolve().parent


def scaled_cloth(n: int, drag_rate: float = 1.0):
    """The built-in cloth with n x n particles, 1 kg in all, drag ``gamma = drag_rate * m``."""
    doc = copy.deepcopy(read_scene_file(scene_path("cloth"), "cloth.toml"))
    doc["particles"]["nx"] = doc["particles"]["ny"] = n
    doc["damping"]["gamma"] = drag_rate * doc["particles"]["total_mass"] / (n * n)
    return scene_from_doc(doc, "cloth.toml", default_name="cloth", overrides={})


# -- references --------------------------------------------------------------------------------
def reference_newton_step(system, state, dt, rtol=1e-10, max_iter=25):
    """Implicit Euler by textbook Newton: full matrix, fresh ``spsolve`` every iteration."""
    x0, v0 = state.x, state.v
    minv = sp.diags(np.repeat(system.inv_mass, system.dim))
    eye = sp.identity(x0.size, format="csc")
    tol = rtol * (1.0 + np.abs(v0).max())
    v = v0.copy()
    for it in range(max_iter + 1):
        x = x0 + dt * v
        g = v - v0 - dt * system.acceleration(x, v)
        if np.abs(g).max() <= tol:
            return State(x, v), it
        K, D = system.jacobians(x, v)
        J = (eye - dt * (minv @ (dt * K + D))).tocsc()
        v = v + spla.spsolve(J, -g.ravel()).reshape(v.shape)
    raise RuntimeError("reference Newton did not converge")


class NumpyFastMassSpring:
    """The same local/global iterations in plain numpy + SuperLU (scipy's default ``splu``)."""

    def __init__(self, system, dt):
        springs = [e for e in system.effects if e.name == "springs"]
        self.i = np.concatenate([e.i for e in springs])
        self.j = np.concatenate([e.j for e in springs])
        self.k = np.concatenate([e.stiffness for e in springs])
        self.rest = np.concatenate([e.rest_length for e in springs])
        self.gamma = sum(e.gamma for e in system.effects if e.name == "damping")
        self.gravity = [e for e in system.effects if e.name == "gravity"]
        n = system.n_particles
        i, j, k = self.i, self.j, self.k
        lap = sp.coo_matrix((np.r_[k, k, -k, -k], (np.r_[i, j, i, j], np.r_[i, j, j, i])),
                            shape=(n, n)).tocsr()
        self.free, self.pinned = ~system.pinned, system.pinned
        self.lap_fp = lap[self.free][:, self.pinned]
        Q = sp.diags(system.mass[self.free] + dt * self.gamma) + dt * dt * lap[self.free][:, self.free]
        self.lu = spla.splu(Q.tocsc())
        self.system, self.dt = system, dt

    def step(self, state, iterations=10):
        s, dt, free = self.system, self.dt, self.free
        xn, vn = state.x, state.v
        y = xn + dt * vn
        base = (s.mass[free, None] * y[free] + dt * self.gamma * xn[free]
                - dt * dt * (self.lap_fp @ y[self.pinned]))
        x = y.copy()
        for _ in range(iterations):
            d = x[self.i] - x[self.j]
            length = np.linalg.norm(d, axis=1)
            p = (self.k * self.rest / np.where(length > 0, length, 1.0))[:, None] * d
            jd = np.zeros_like(x)
            for c in range(x.shape[1]):
                jd[:, c] = np.bincount(self.i, p[:, c], x.shape[0]) - np.bincount(self.j, p[:, c], x.shape[0])
            for e in self.gravity:
                jd += e.force(x, vn)
            rhs = base + dt * dt * jd[free]
            x[free] = np.column_stack([self.lu.solve(rhs[:, c].copy()) for c in range(x.shape[1])])
        return State(x, (x - xn) / dt)


# -- measurements ------------------------------------------------------------------------------
def timed(f, *args):
    t = time.perf_counter()
    out = f(*args)
    return time.perf_counter() - t, out


def implicit_euler_vs_reference(n: int, steps: int, warm: int = 2) -> dict:
    """Reference Newton, mslab's step (numpy evaluations) and mslab's step on the compiled view.

    All three step from the same states (mslab's numpy trajectory); the compiled view is
    the ``backend="numba"`` path of ``simulate`` (compiled forces and Jacobians, the same
    Newton and linear algebra).
    """
    from mslab.fast.model import ForceModel
    from mslab.fast.newton import CompiledSystem

    scene = scaled_cloth(n)
    system, dt = scene.system, 1 / 60
    view = CompiledSystem(system, ForceModel(system))
    view.warm()
    ie = mslab.get_method("implicit_euler")
    state = scene.state0
    for _ in range(warm):  # Jacobian pattern, first factorisation, on both paths
        ie.step(view, state, dt)
        state = ie.step(system, state, dt)
    t_ms, t_ref, t_view, diff, diff_view, iters = [], [], [], [], [], []
    work = {}
    for _ in range(steps):
        tr, (ref, it) = timed(reference_newton_step, system, state, dt)
        before = system.counters.snapshot()
        tm, new = timed(ie.step, system, state, dt)
        work = {k: work.get(k, 0) + v for k, v in system.counters.since(before).items()}
        tv, compiled = timed(ie.step, view, state, dt)
        t_ref.append(tr)
        t_ms.append(tm)
        t_view.append(tv)
        iters.append(it)
        diff.append(float(np.abs(ref.x - new.x).max()))
        diff_view.append(float(np.abs(compiled.x - new.x).max()))
        state = new
    return {"n": n, "unknowns": 3 * int(np.count_nonzero(~system.pinned)), "steps": steps,
            "mslab_s_per_step": float(np.mean(t_ms)), "reference_s_per_step": float(np.mean(t_ref)),
            "compiled_s_per_step": float(np.mean(t_view)),
            "speedup": float(np.sum(t_ref) / np.sum(t_ms)),
            "speedup_compiled": float(np.sum(t_ref) / np.sum(t_view)),
            "max_position_difference": max(diff), "max_difference_compiled_numpy": max(diff_view),
            "reference_iterations_per_step": float(np.mean(iters)), "mslab_work": work}


def fms_vs_reference(n: int, repeats: int) -> dict:
    scene = scaled_cloth(n)
    system, dt = scene.system, 1 / 30
    fms = mslab.get_method("fast_mass_spring")
    ref = NumpyFastMassSpring(system, dt)
    state = scene.state0
    for _ in range(3):  # compile the local step, factor the global matrix
        state = fms.step(system, state, dt)
    t_ms, t_ref, diff = [], [], []
    for _ in range(repeats):
        tr, a = timed(ref.step, state)
        tm, b = timed(fms.step, system, state, dt)
        t_ref.append(tr)
        t_ms.append(tm)
        diff.append(float(np.abs(a.x - b.x).max()))
        state = b
    return {"n": n, "frame_ms": 1e3 * float(np.median(t_ms)),
            "reference_frame_ms": 1e3 * float(np.median(t_ref)),
            "speedup": float(np.median(np.array(t_ref) / np.array(t_ms))),
            "max_position_difference": max(diff)}


def fms_vs_implicit_euler(n: int, frames: int) -> dict:
    """FMS frames and implicit Euler steps from the same states; the relative difference per frame."""
    scene = scaled_cloth(n)
    system, dt = scene.system, 1 / 30
    fms, ie = mslab.get_method("fast_mass_spring"), mslab.get_method("implicit_euler")
    state = scene.state0
    fms.step(system, state, dt)
    ie.step(system, state, dt)
    t_f, t_i, rel = [], [], []
    for _ in range(frames):
        ti, exact = timed(ie.step, system, state, dt)
        tf, new = timed(fms.step, system, state, dt)
        t_f.append(tf)
        t_i.append(ti)
        rel.append(float(np.abs(new.x - exact.x).max() / np.abs(exact.x - state.x).max()))
        state = new
    return {"n": n, "fms_frame_ms": 1e3 * float(np.median(t_f)),
            "implicit_euler_step_ms": 1e3 * float(np.median(t_i)),
            "ratio": float(np.median(np.array(t_i) / np.array(t_f))),
            "relative_difference_median": float(np.median(rel)),
            "relative_difference_max": float(np.max(rel))}


def scaling(sizes, fms_repeats: int, ie_steps: int) -> dict:
    rows = []
    for n in sizes:
        scene = scaled_cloth(n)
        system = scene.system
        fms, ie = mslab.get_method("fast_mass_spring"), mslab.get_method("implicit_euler")
        s = fms.step(system, scene.state0, 1 / 30)
        tf = np.median([timed(fms.step, system, s, 1 / 30)[0] for _ in range(fms_repeats)])
        state = ie.step(system, scene.state0, 1 / 60)
        ti = []
        for _ in range(ie_steps):
            t, state = timed(ie.step, system, state, 1 / 60)
            ti.append(t)
        rows.append({"n": n, "particles": n * n, "fms_frame_s": float(tf),
                     "implicit_euler_step_s": float(np.mean(ti))})
    p = np.log([r["particles"] for r in rows])
    return {"rows": rows,
            "fms_slope": float(np.polyfit(p, np.log([r["fms_frame_s"] for r in rows]), 1)[0]),
            "implicit_euler_slope":
                float(np.polyfit(p, np.log([r["implicit_euler_step_s"] for r in rows]), 1)[0])}


def machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "load_average": os.getloadavg(),
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}


@single_threaded_blas
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats, smaller cloths")
    args = parser.parse_args()
    q = args.quick
    out = {"machine_start": machine()}
    out["implicit_euler"] = [implicit_euler_vs_reference(n, steps) for n, steps in
                             ([(30, 3)] if q else [(70, 5), (100, 4)])]
    out["fast_mass_spring"] = fms_vs_reference(40 if q else 81, 5 if q else 15)
    out["fms_vs_implicit_euler"] = fms_vs_implicit_euler(40 if q else 81, 4 if q else 12)
    out["scaling"] = scaling([20, 30, 40] if q else [20, 40, 60, 81], 3 if q else 7, 2 if q else 4)
    out["machine_end"] = machine()
    print(json.dumps(out, indent=1))
    if not q:
        (HERE / "implicit_cloth.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
