"""The measurements of ``mslab bench``: mslab's speed as ratios to references timed in the same run.

Every number is the median of repeats, after a warm-up call (compile time stays out), and
every target compares two timings taken in this run on this machine, interleaved repeat by
repeat (median of the per-repeat ratios), so the ratios hold on a loaded machine better
than absolute times do. Four experiments (issue 5, item 3):

``chain``
    20-mass 3D chain, RK4, dt = 1e-3: time per step of ``mslab.simulate`` (compiled loop)
    and of the numpy loop, both divided by a hand-written numba RK4 loop
    (:func:`benchmarks.references.ref_rk4`). Target: mslab <= 3 x the reference.
``matched_error``
    Same chain to t = 2: scipy ``solve_ivp(RK45)`` (rtol 1e-6, compiled right-hand side,
    its best case) against mslab RK4 at the largest dt of a sweep whose final error is no
    larger; errors against ``solve_ivp(DOP853, rtol = atol = 1e-13)``. Target: mslab faster.
``cloth_forces``
    Spring forces of a 300 x 300 cloth (5.4e5 springs): the compiled force of mslab
    (``ForceModel.force``: the scene's kernels, composed) evaluations per second relative
    to a single-thread compiled kernel
    (:func:`benchmarks.references.ref_spring_force`); the numpy path for comparison; the
    log-log slope of time against the number of springs from 1e3 to 1e6. Targets:
    ratio >= 0.7, slope <= 1.1.
``implicit``
    Implicit Euler (Newton) on a 100 x 100 cloth: time per step and per Newton iteration,
    the split into Jacobian assembly and sparse solve, and the spring Jacobian assembly
    into its fixed CSR pattern against the COO -> CSR assembly it replaced.
"""

from __future__ import annotations

import datetime
import platform
import statistics
import subprocess
import time
from collections.abc import Callable

import numpy as np

from benchmarks import references as ref
from mslab import fast


def median_time(fn: Callable[[], object], repeats: int = 5, min_time: float = 0.05) -> float:
    """Median over ``repeats`` of the time of one call of ``fn`` (seconds).

    One warm-up call first; each repeat runs ``fn`` often enough to last ``min_time``.
    """
    fn()
    start = time.perf_counter()
    fn()
    once = max(time.perf_counter() - start, 1e-7)
    number = max(1, int(min_time / once))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - start) / number)
    return statistics.median(times)


def paired_times(fn_a: Callable[[], object], fn_b: Callable[[], object], repeats: int = 7,
                 min_time: float = 0.05) -> tuple[float, float, float]:
    """Interleaved timing of two functions: ``(median time a, median time b, median of a/b)``.

    Each repeat times ``a`` then ``b`` back to back, so a burst of load from other jobs hits
    both; the median of the per-repeat ratios is steadier than a ratio of two medians.
    """
    counts = []
    for fn in (fn_a, fn_b):
        fn()
        start = time.perf_counter()
        fn()
        counts.append(max(1, int(min_time / max(time.perf_counter() - start, 1e-7))))
    ta, tb = [], []
    for _ in range(repeats):
        for fn, number, out in ((fn_a, counts[0], ta), (fn_b, counts[1], tb)):
            start = time.perf_counter()
            for _ in range(number):
                fn()
            out.append((time.perf_counter() - start) / number)
    ratio = statistics.median(a / b for a, b in zip(ta, tb, strict=True))
    return statistics.median(ta), statistics.median(tb), ratio


def machine() -> dict:
    """CPU model, core count, library versions and the date (UTC) of this run."""
    import numba
    import scipy

    model = platform.processor() or platform.machine()
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=5).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                model = line.split(":", 1)[1].strip()
    except (OSError, subprocess.SubprocessError):
        pass
    import os

    return {"cpu": model, "cores": os.cpu_count(), "python": platform.python_version(),
            "numpy": np.__version__, "scipy": scipy.__version__, "numba": numba.__version__,
            "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")}


# -- 1. the chain: time per step --------------------------------------------------------
def chain_scene():
    from mslab.scenes.generators import chain

    return chain(20, dim=3)


def _ref_args(system):
    """Arguments of the reference kernels: the springs' flat arrays and gravity g."""
    from mslab.effects import Gravity, Springs

    springs = next(e for e in system.effects if type(e) is Springs)
    g = np.zeros(system.dim)
    for e in system.effects:
        if type(e) is Gravity:
            g = g + e.g
    return springs, np.ascontiguousarray(system.inv_mass), g


def bench_chain(quick: bool = False) -> dict:
    """Time per RK4 step: mslab (compiled loop), mslab numpy loop, hand-written numba loop."""
    import mslab

    scene = chain_scene()
    dt = 1e-3
    n_steps = 2000 if quick else 10000
    repeats = 7 if quick else 15
    springs, inv_mass, g = _ref_args(scene.system)
    x0, v0 = scene.state0.x, scene.state0.v

    def run_ref():
        x, v = x0.copy(), v0.copy()
        ref.ref_rk4(x, v, inv_mass, springs.i, springs.j, springs.stiffness, springs.rest_length, g,
                    dt, n_steps)
        return x

    def run_mslab(backend, steps):
        return mslab.simulate(scene, "rk4", dt=dt, t_end=steps * dt, save_every=steps,
                              backend=backend, check_stability=False)

    # same answer first (the reference is the same method on the same forces)
    agree = float(np.max(np.abs(run_ref() - run_mslab("numba", n_steps).x[-1])))
    t_fast, t_ref, ratio = paired_times(lambda: run_mslab("numba", n_steps), run_ref, repeats)
    t_fast, t_ref = t_fast / n_steps, t_ref / n_steps
    n_np = 200 if quick else 1000
    t_numpy = median_time(lambda: run_mslab("numpy", n_np), 3 if quick else 5, min_time=0.0) / n_np
    return {"scene": "chain(20, dim=3)", "method": "rk4", "dt": dt, "steps": n_steps,
            "ref_time_per_step": t_ref, "mslab_time_per_step": t_fast, "numpy_time_per_step": t_numpy,
            "ratio": ratio, "numpy_ratio": t_numpy / t_ref, "max_difference_to_ref": agree}


# -- 2. matched final error against scipy's RK45 ----------------------------------------
def bench_matched_error(quick: bool = False) -> dict:
    """mslab RK4 against ``solve_ivp(RK45)`` at no larger final error on the chain."""
    from scipy.integrate import solve_ivp

    import mslab

    scene = chain_scene()
    model = fast.ForceModel(scene.system)  # scipy gets the compiled right-hand side (its best case)
    shape = scene.state0.x.shape
    size = scene.state0.x.size
    t_end = 2.0

    def f(t, y):
        x, v = y[:size].reshape(shape), y[size:].reshape(shape)
        a, _ = model.rhs(x, v)
        return np.concatenate([v.ravel(), a.ravel()])

    y0 = np.concatenate([scene.state0.x.ravel(), scene.state0.v.ravel()])
    exact = solve_ivp(f, (0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-13).y[:, -1]

    def error(y):
        return float(np.max(np.abs(y - exact)))

    rtol, atol = 1e-6, 1e-8

    def run_scipy():
        return solve_ivp(f, (0, t_end), y0, method="RK45", rtol=rtol, atol=atol)

    sol = run_scipy()
    err_scipy = error(sol.y[:, -1])

    def run_mslab(dt):  # the compiled loop (backend="auto" would keep so short a run in numpy)
        return mslab.simulate(scene, "rk4", dt=dt, t_end=t_end, save_every=10**9, backend="numba")

    chosen = None
    for n in (100, 200, 400, 800, 1600, 3200, 6400, 12800):  # dt = 0.02 is inside rk4's limit
        traj = run_mslab(t_end / n)
        err = error(np.concatenate([traj.x[-1].ravel(), traj.v[-1].ravel()]))
        if err <= err_scipy:
            chosen = (t_end / n, err)
            break
    repeats = 3 if quick else 7
    t_scipy = median_time(run_scipy, repeats, min_time=0.0)
    if chosen is None:
        return {"scipy_error": err_scipy, "scipy_time": t_scipy, "mslab_time": float("nan"),
                "ratio": float("nan"), "note": "no dt of the sweep reached scipy's error"}
    dt, err = chosen
    t_mslab = median_time(lambda: run_mslab(dt), repeats)
    return {"t_end": t_end, "scipy_method": "RK45", "scipy_rtol": rtol, "scipy_atol": atol,
            "scipy_error": err_scipy, "scipy_n_force": int(sol.nfev), "scipy_time": t_scipy,
            "mslab_method": "rk4", "mslab_dt": dt, "mslab_error": err,
            "mslab_n_force": int(4 * round(t_end / dt)), "mslab_time": t_mslab,
            "ratio": t_mslab / t_scipy}


# -- 3. spring forces of a big cloth --------------------------------------------------------
def cloth_springs(n: int, from_scene: bool = True):
    """The Springs effect of ``cloth(n, n)`` and its positions.

    ``from_scene=False`` builds the same springs (structural, shear, bend of the cloth
    generator, rest length = initial length) without the SceneBuilder, which takes
    seconds for large cloths.
    """
    from mslab.effects import Springs
    from mslab.scenes.generators import cloth, grid_springs

    if from_scene:
        scene = cloth(n, n)
        return scene.springs(), scene.state0.x
    gx, gz = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(-1.0, 0.0, n), indexing="xy")
    x = np.stack([gx.ravel(), np.zeros(n * n), gz.ravel()], axis=1)
    pairs, k = [], []
    for kind, stiffness in (("structural", 500.0), ("shear", 50.0), ("bend", 5.0)):
        p = grid_springs((n, n), kind)
        pairs.append(p)
        k.append(np.full(len(p), stiffness))
    pairs = np.concatenate(pairs)
    rest = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    return Springs(pairs, np.concatenate(k), rest, np.zeros(len(pairs)), n * n), x


def bench_cloth_forces(quick: bool = False) -> dict:
    """Spring-force evaluations per second (mslab, numpy, reference) and the cost slope."""
    from mslab.system import System

    repeats = 7 if quick else 15
    rng = np.random.default_rng(0)
    springs, x0 = cloth_springs(300, from_scene=not quick)
    x = x0 + 0.01 * rng.normal(size=x0.shape)   # stretched and compressed springs
    v = np.zeros_like(x)
    buf = np.empty_like(x)

    def compiled(s):
        """The compiled force of a System made of these springs (mslab's composed kernels)."""
        n = s.n
        return fast.ForceModel(System(np.ones(n), np.zeros(n, dtype=bool), [s], 3))

    model = compiled(springs)

    def run_ref():
        ref.ref_spring_force(x, springs.i, springs.j, springs.stiffness, springs.rest_length, buf)

    run_ref()
    agree = float(np.max(np.abs(model.force(x, v)[0] - buf)))
    t_ref, t_fast, ratio = paired_times(run_ref, lambda: model.force(x, v), repeats)
    t_numpy = median_time(lambda: springs.force(x, v), 3)
    sizes, times = [], []
    for n in (13, 41, 129, 408):  # 1e3 .. 1e6 springs
        s, xn = cloth_springs(n, from_scene=False)
        xn = xn + 0.01 * rng.normal(size=xn.shape)
        vn = np.zeros_like(xn)
        mn = compiled(s)
        sizes.append(len(s.i))
        times.append(median_time(lambda mn=mn, xn=xn, vn=vn: mn.force(xn, vn), repeats))
    slope = float(np.polyfit(np.log(sizes), np.log(times), 1)[0])
    return {"n_springs": int(len(springs.i)), "ref_evals_per_s": 1.0 / t_ref,
            "mslab_evals_per_s": 1.0 / t_fast, "numpy_evals_per_s": 1.0 / t_numpy,
            "ratio": ratio, "numpy_ratio": t_ref / t_numpy,
            "ns_per_spring": 1e9 * t_fast / len(springs.i), "max_difference_to_ref": agree,
            "slope_sizes": sizes, "slope_times": times, "slope": slope}


# -- 4. implicit Euler on a 100 x 100 cloth -------------------------------------------------
def bench_implicit(quick: bool = False) -> dict:
    """Implicit Euler: time per step and per Newton iteration; Jacobian assembly vs solve."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    import mslab
    from mslab.effects.base import pair_blocks
    from mslab.scenes.generators import cloth

    n = 60 if quick else 100  # --quick: a smaller cloth (the direct solve of 100 x 100 takes seconds)
    scene = cloth(n, n)
    system = scene.system
    dt, steps = 1e-2, (2 if quick else 5)
    traj = mslab.simulate(scene, "implicit_euler", dt=dt, t_end=steps * dt, save_every=steps)
    st = traj.stats
    x, v = traj.x[-1], traj.v[-1]
    repeats = 1 if quick else 5
    t_jac = median_time(lambda: system.jacobians(x, v), repeats, min_time=0.0)
    K, D = system.jacobians(x, v)
    lin = K * dt if D is None else K * dt + D
    J = (sp.identity(x.size, format="csc") - dt * (system.inv_mass_diag @ lin)).tocsc()
    rhs = np.ones(x.size)
    t_solve = median_time(lambda: spla.spsolve(J, rhs), repeats, min_time=0.0)
    springs = scene.springs()
    blocks = np.random.default_rng(1).normal(size=(len(springs.i), 3, 3))
    t_coo = median_time(lambda: pair_blocks(blocks, springs.i, springs.j, springs.n), repeats, 0.0)
    t_pattern = median_time(lambda: springs._assemble(blocks), repeats, 0.0)
    return {"scene": f"cloth({n}, {n})", "n_springs": int(len(springs.i)), "dt": dt,
            "steps": st.steps, "n_iter": st.n_iter, "n_force": st.n_force, "n_jac": st.n_jac,
            "n_solve": st.n_solve, "time_per_step": st.wall_time / st.steps,
            "time_per_newton_iteration": st.wall_time / max(1, st.n_iter),
            "jacobian_time": t_jac, "solve_time": t_solve,
            "assembly_coo_time": t_coo, "assembly_pattern_time": t_pattern,
            "assembly_speedup": t_coo / t_pattern}


# -- all -------------------------------------------------------------------------------------
TARGETS = (
    # (key, experiment, field, comparison, bound, text)
    ("chain_rk4_step", "chain", "ratio", "<=", 3.0, "RK4 step, 20-mass chain: mslab / numba loop"),
    ("matched_error", "matched_error", "ratio", "<", 1.0, "same final error: mslab rk4 / scipy RK45 time"),
    ("cloth_forces", "cloth_forces", "ratio", ">=", 0.7, "300x300 cloth spring forces/s: mslab / kernel"),
    ("cloth_slope", "cloth_forces", "slope", "<=", 1.1, "log-log slope of force time vs springs"),
)


def run_all(quick: bool = False, progress: Callable[[str], None] | None = None) -> dict:
    """Run the four experiments; returns ``{"machine", "quick", experiments..., "targets"}``."""
    doc = {"machine": machine(), "quick": quick}
    for name, fn in (("chain", bench_chain), ("matched_error", bench_matched_error),
                     ("cloth_forces", bench_cloth_forces), ("implicit", bench_implicit)):
        if progress:
            progress(name)
        start = time.perf_counter()
        doc[name] = fn(quick)
        doc[name]["bench_seconds"] = time.perf_counter() - start
    targets = []
    for key, exp, fld, op, bound, text in TARGETS:
        value = doc[exp][fld]
        met = bool({"<=": value <= bound, "<": value < bound, ">=": value >= bound}[op])
        targets.append({"target": key, "what": text, "value": value, "goal": f"{op} {bound:g}", "met": met})
    doc["targets"] = targets
    return doc


def table(doc: dict) -> str:
    """The targets and the main numbers as a Markdown table."""
    c, m, f, im = doc["chain"], doc["matched_error"], doc["cloth_forces"], doc["implicit"]
    rows = ["| measurement | value | goal | met |", "|---|---|---|---|"]
    for t in doc["targets"]:
        rows.append(f"| {t['what']} | {t['value']:.3g} | {t['goal']} | {'yes' if t['met'] else 'NO'} |")
    rows += [
        f"| RK4 step, plain numpy loop / numba loop | {c['numpy_ratio']:.3g} | (for comparison) | |",
        f"| RK4 step: numba loop / mslab / numpy (µs) | {1e6 * c['ref_time_per_step']:.3g} / "
        f"{1e6 * c['mslab_time_per_step']:.3g} / {1e6 * c['numpy_time_per_step']:.3g} | | |",
        f"| matched error: scipy RK45 rtol {m.get('scipy_rtol', 0):g} error, time (ms), n_force | "
        f"{m['scipy_error']:.2g}, {1e3 * m['scipy_time']:.3g}, {m.get('scipy_n_force', 0)} | | |",
        f"| matched error: mslab rk4 dt, error, time (ms), n_force | {m.get('mslab_dt', float('nan')):g}, "
        f"{m.get('mslab_error', float('nan')):.2g}, {1e3 * m['mslab_time']:.3g}, "
        f"{m.get('mslab_n_force', 0)} | | |",
        f"| cloth forces/s, {f['n_springs']} springs: kernel / mslab / numpy | "
        f"{f['ref_evals_per_s']:.3g} / {f['mslab_evals_per_s']:.3g} / {f['numpy_evals_per_s']:.3g} | | |",
        f"| cloth forces: numpy / kernel | {f['numpy_ratio']:.3g} | (for comparison) | |",
        f"| implicit Euler {im['scene']}: s per step, per Newton iteration | "
        f"{im['time_per_step']:.3g}, {im['time_per_newton_iteration']:.3g} | reported | |",
        f"| implicit Euler: Jacobian assembly, sparse solve (s) | {im['jacobian_time']:.3g}, "
        f"{im['solve_time']:.3g} | reported | |",
        f"| spring Jacobian: COO->CSR / fixed pattern (s) | {im['assembly_coo_time']:.3g} / "
        f"{im['assembly_pattern_time']:.3g} ({im['assembly_speedup']:.3g}x) | reported | |",
    ]
    return "\n".join(rows)
