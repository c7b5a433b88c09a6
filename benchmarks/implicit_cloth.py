"""Implicit methods at cloth scale (issue 12): mslab against references written here.

Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/implicit_cloth.py [--quick] [--implicit-only]

Measures, in one run with the machine recorded (times are medians or sums of interleaved
repeats, ratios compare timings of this run):

1. implicit Euler step on N x N cloths (N = 70, 100; dt = 1/60): mslab's Newton (kept
   factorisations, symmetric free-dof matrix; with numpy evaluations and on the compiled
   view of ``backend="numba"``) against textbook Newtons written here, same tolerance:
   a fresh ``spsolve`` (SuperLU) every iteration, a fresh CHOLMOD factorisation (analysis
   and numeric) every iteration, and CHOLMOD with its analysis kept; all step from the same
   states, interleaved repeats, per-step medians (``--implicit-only``: this item and the
   next only); the clamped Newton matrix (``ImplicitRK(..., newton_hessian="clamped")``) against exact
   Newton from the flat sheet at dt = 1/60 and 1/30 (buckling steps);
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
from mslab.errors import StepFailure
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


#: iterations of the CHOLMOD references that met an indefinite matrix (solved by SuperLU)
INDEFINITE = [0]


def reference_cholmod_newton_step(system, state, dt, rtol=1e-10, max_iter=25, keep_analysis=None):
    """Implicit Euler by textbook Newton with a fresh CHOLMOD factorisation every iteration.

    The symmetric form on the free dofs, ``(M - h^2 K - h D) dv = -M g``, assembled with scipy
    from the effects' numpy Jacobians and factored by CHOLMOD (cvxopt) every iteration: its
    symbolic analysis and numeric factorisation (``keep_analysis``: a dict that keeps the
    analysis of the first matrix for later ones, numeric factorisation only).
    """
    import cvxopt
    import cvxopt.cholmod

    x0, v0 = state.x, state.v
    free = np.repeat(~system.pinned, system.dim)
    mass = sp.diags(np.repeat(system.mass, system.dim)[free])
    tol = rtol * (1.0 + np.abs(v0).max())
    v = v0.copy()
    for it in range(max_iter + 1):
        x = x0 + dt * v
        g = v - v0 - dt * system.acceleration(x, v)
        if np.abs(g).max() <= tol:
            return State(x, v), it
        K, D = system.jacobians(x, v)
        A = (mass - (dt * dt * K + dt * D).tocsr()[free][:, free]).tocoo()
        low = A.row >= A.col
        S = cvxopt.spmatrix(A.data[low], A.row[low].astype(np.int64), A.col[low].astype(np.int64), A.shape)
        rhs = -(mass @ g.ravel()[free])
        key = (A.row[low].tobytes(), A.col[low].tobytes())  # scipy drops exact zeros: patterns vary
        if keep_analysis is None or keep_analysis.get("key") != key:
            F = cvxopt.cholmod.symbolic(S, uplo="L")
            if keep_analysis is not None:
                keep_analysis.update(key=key, F=F)
        else:
            F = keep_analysis["F"]
        dv = np.zeros(v.size)
        try:
            cvxopt.cholmod.numeric(S, F)
            b = cvxopt.matrix(rhs)
            cvxopt.cholmod.solve(F, b)
            dv[free] = np.array(b).ravel()
        except ArithmeticError:  # not positive definite (buckling): SuperLU for this iteration
            INDEFINITE[0] += 1
            dv[free] = spla.spsolve(A.tocsc(), rhs)
        v = v + dv.reshape(v.shape)
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


def implicit_euler_vs_reference(n: int, steps: int, warm: int = 2, repeats: int = 3) -> dict:
    """mslab's step (numpy evaluations; compiled path) against three textbook Newtons.

    References: a fresh ``spsolve`` (SuperLU) per iteration; a fresh CHOLMOD factorisation
    per iteration (symbolic analysis and numeric factorisation, the issue's measure); the
    same with CHOLMOD's analysis kept (numeric factorisation only). All step from the same
    states (mslab's numpy trajectory); each state is timed ``repeats`` times, the five runs
    interleaved, and the per-step median is taken. The compiled view is the
    ``backend="numba"`` path of ``simulate`` (compiled forces, Newton matrix and energy, the
    same Newton and linear algebra).
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
    kept = {}
    runs = {"spsolve": lambda s: reference_newton_step(system, s, dt)[0],
            "cholmod": lambda s: reference_cholmod_newton_step(system, s, dt)[0],
            "cholmod_kept_analysis":
                lambda s: reference_cholmod_newton_step(system, s, dt, keep_analysis=kept)[0],
            "mslab": lambda s: ie.step(system, s, dt), "compiled": lambda s: ie.step(view, s, dt)}
    times = {k: [] for k in runs}
    diff = {k: 0.0 for k in runs}
    work = {}
    for _ in range(steps):
        per = {k: [] for k in runs}
        out = {}
        for rep in range(repeats):
            for k, f in runs.items():
                if k == "spsolve" and rep:  # SuperLU is 10x slower: one timing per state
                    continue
                before = system.counters.snapshot()
                t, out[k] = timed(f, state)
                if k == "mslab" and rep == 0:
                    work = {w: work.get(w, 0) + c for w, c in system.counters.since(before).items()}
                per[k].append(t)
        for k in runs:
            times[k].append(float(np.median(per[k])))
            diff[k] = max(diff[k], float(np.abs(out[k].x - out["cholmod"].x).max()))
        state = out["mslab"]
    tot = {k: float(np.sum(v)) for k, v in times.items()}
    return {"n": n, "unknowns": 3 * int(np.count_nonzero(~system.pinned)), "steps": steps, "repeats": repeats,
            "s_per_step": {k: v / steps for k, v in tot.items()},
            "speedup_vs_fresh_cholmod": tot["cholmod"] / tot["mslab"],
            "speedup_vs_fresh_cholmod_compiled": tot["cholmod"] / tot["compiled"],
            "speedup_vs_kept_analysis_cholmod_compiled": tot["cholmod_kept_analysis"] / tot["compiled"],
            "speedup_vs_spsolve": tot["spsolve"] / tot["mslab"],
            "speedup_vs_spsolve_compiled": tot["spsolve"] / tot["compiled"],
            "max_position_difference_from_fresh_cholmod": diff,
            "cholmod_reference_indefinite_iterations": INDEFINITE[0], "mslab_work_per_step":
                {k: v / steps for k, v in work.items()}}


def clamped_vs_exact(n: int, dt: float, steps: int) -> dict:
    """The clamped Newton matrix (``newton_hessian="clamped"``) against exact Newton, compiled path.

    From the flat sheet at rest (the buckling first steps) at ``dt``: both step the same
    states; positions compared, work and time per step.
    """
    from mslab.fast.model import ForceModel
    from mslab.fast.newton import CompiledSystem

    scene = scaled_cloth(n)
    system = scene.system
    view = CompiledSystem(system, ForceModel(system))
    view.warm()
    exact = mslab.get_method("implicit_euler")
    clamped = mslab.ImplicitRK([[1]], [1], name="implicit_euler_clamped", order=1, newton_hessian="clamped")
    state = scene.state0
    t = {"exact": [], "clamped": []}
    work = {"exact": {}, "clamped": {}}
    diff, failures = 0.0, []
    for _ in range(steps):
        out = {}
        for k, m in (("exact", exact), ("clamped", clamped)):
            before = system.counters.snapshot()
            try:
                dt_k, out[k] = timed(m.step, view, state, dt)
            except StepFailure as err:  # recorded: the clamped matrix may stall
                failures.append(f"{k}: {err}")
                continue
            t[k].append(dt_k)
            work[k] = {w: work[k].get(w, 0) + c for w, c in system.counters.since(before).items()}
        if "clamped" in out:
            diff = max(diff, float(np.abs(out["exact"].x - out["clamped"].x).max()))
        state = out["exact"]
    return {"n": n, "dt": dt, "steps": steps, "failures": failures,
            "s_per_step": {k: float(np.median(v)) if v else None for k, v in t.items()},
            "time_ratio_clamped_over_exact_median": float(np.median(t["clamped"]) / np.median(t["exact"]))
            if t["clamped"] else None,
            "max_position_difference": diff, "work": work}


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
    out = {"machine_start": machine()}
    parser.add_argument("--implicit-only", action="store_true", help="only the implicit Euler rows")
    args = parser.parse_args()
    q = args.quick
    out["implicit_euler"] = []
    for n, steps in [(30, 3)] if q else [(70, 6), (100, 4)]:
        out["implicit_euler"].append(implicit_euler_vs_reference(n, steps))
        print(json.dumps(out["implicit_euler"][-1], indent=1), flush=True)
    out["clamped_vs_exact"] = [clamped_vs_exact(n, dt, steps) for n, dt, steps in
                               ([(20, 1 / 30, 3)] if q else [(70, 1 / 60, 6), (70, 1 / 30, 6)])]
    if not args.implicit_only:
        out["fast_mass_spring"] = fms_vs_reference(40 if q else 81, 5 if q else 15)
        out["fms_vs_implicit_euler"] = fms_vs_implicit_euler(40 if q else 81, 4 if q else 12)
        out["scaling"] = scaling([20, 30, 40] if q else [20, 40, 60, 81], 3 if q else 7, 2 if q else 4)
    out["machine_end"] = machine()
    print(json.dumps(out, indent=1))
    if not q:  # --implicit-only: the other sections of the file are kept from their run
        path = HERE / "implicit_cloth.json"
        kept = json.loads(path.read_text()) if args.implicit_only and path.exists() else {}
        if args.implicit_only:
            out["implicit_machine_start"], out["implicit_machine_end"] = out.pop("machine_start"), \
                out.pop("machine_end")
        path.write_text(json.dumps({**kept, **out}, indent=1) + "\n")


if __name__ == "__main__":
    main()
