"""mslab against NVIDIA Warp's CPU backend on the same cloth (issue 14).

Usage (from a checkout; ``warp-lang`` is an optional benchmark dependency, never a runtime one)::

    pip install warp-lang
    python benchmarks/warp_cloth.py            # 100x100 and 300x300, writes warp_results.json
    python benchmarks/warp_cloth.py --quick    # fewer repeats

What is compared, per cloth size:

* the **same cloth** (``mslab.scenes.generators.cloth(n, n)``: structural, shear and bend
  springs, gravity, two pinned corners; positions perturbed by 1 mm so every spring
  pulls), its arrays handed to Warp unchanged (int32 indices, float64 everything else);
* the **same float64 update**, symplectic Euler: ``a = M^-1 (m g + f_springs)``,
  ``v += h a``, ``x += h v``, in the same operations and summation order (the pair
  force in mslab's scale form ``f_q = k (L / l - 1) d``, ``-k d`` at zero length). Warp runs it as
  two kernel launches per step (springs with atomic adds, then a fused integrate that also
  resets the force array to the weights ``m g``), the usual Warp cloth given mslab's own
  trick for constant forces; mslab runs its compiled splitting loop
  (``fast.Stepper.advance``, the loop ``simulate`` runs) over its scene's own kernels;
* **results**: both advance the same number of steps and must agree to 1e-12 (relative
  to the size of the positions); a mismatch stops the benchmark;
* **timing**: compile time excluded (a warm-up of both first), interleaved repeats (Warp,
  then mslab, back to back, so a burst of load from other jobs hits both), the ratio
  mslab/Warp per repeat, its median with min and max, on two clocks: the process's CPU
  time (what the step costs one core; steady on a shared machine) and wall time (what a
  user waits; moved by other jobs); the machine, library versions and the load average
  recorded;
* **threads**: Warp's CPU backend runs a launch on one thread; mslab is timed on one
  thread and on every core numba sees (its default), the same run bitwise
  (:mod:`mslab.effects.spring_batches`). Warp gets the springs in the order of mslab's
  batches, so both sum every particle's forces in the same order;
* **the kernel's limit**: the spring kernel alone (mslab's ``spring_kernel`` as compiled by
  ``mslab.fast``, one thread) against the arithmetic it cannot avoid, one square root and one
  division per spring, timed as a loop of only those over as many numbers (vectorised by the
  compiler: the machine's throughput for them), interleaved, in CPU time. The issue-14
  "share of copy bandwidth" is gone: the kernel reads far fewer bytes from memory than it
  counted, and the kernel is bound by its arithmetic, not by memory.
"""


import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.suite import machine  # noqa: E402


def load_warp():
    """The ``warp`` module on its CPU device, or the reason it is not available."""
    try:
        import warp as wp
    except ImportError as err:
        return None, f"warp-lang does not import ({err}); pip install warp-lang"
    wp.config.quiet = True
    wp.init()
    return wp, None


def build_cloth(n: int, seed: int = 0):
    """The cloth scene, its perturbed initial state and its flat arrays."""
    from mslab.effects import Gravity, Springs
    from mslab.scenes.generators import cloth

    scene = cloth(n, n)
    system = scene.system
    rng = np.random.default_rng(seed)
    x0 = scene.state0.x + 1e-3 * rng.normal(size=scene.state0.x.shape)
    x0[system.pinned] = scene.state0.x[system.pinned]
    v0 = np.zeros_like(x0)
    springs = next(e for e in system.effects if type(e) is Springs)
    gravity = next(e for e in system.effects if type(e) is Gravity)
    return scene, x0, v0, springs, gravity


def warp_stepper(wp, x0, v0, springs, gravity, inv_mass, dt: float):
    """A function ``step(n)`` advancing Warp's copy of the cloth by ``n`` steps, and its state."""
    f64 = wp.float64

    @wp.kernel
    def spring_forces(x: wp.array(dtype=wp.vec3d), i: wp.array(dtype=wp.int32), j: wp.array(dtype=wp.int32),
                      k: wp.array(dtype=f64), rest: wp.array(dtype=f64), f: wp.array(dtype=wp.vec3d)):
        q = wp.tid()
        a = i[q]
        b = j[q]
        d = x[a] - x[b]
        length = wp.length(d)
        inv_l = f64(0.0)
        if length > f64(0.0):
            inv_l = f64(1.0) / length
        s = k[q] * (rest[q] * inv_l - f64(1.0))
        fq = s * d
        wp.atomic_add(f, a, fq)
        wp.atomic_sub(f, b, fq)

    @wp.kernel
    def integrate(x: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d), f: wp.array(dtype=wp.vec3d),
                  fg: wp.array(dtype=wp.vec3d), inv_m: wp.array(dtype=f64), h: f64):
        p = wp.tid()
        a = inv_m[p] * f[p]
        vn = v[p] + h * a
        v[p] = vn
        x[p] = x[p] + h * vn
        f[p] = fg[p]

    dev = "cpu"
    x = wp.array(x0, dtype=wp.vec3d, device=dev)
    v = wp.array(v0, dtype=wp.vec3d, device=dev)
    fg = wp.array(gravity.kernel_params()[0], dtype=wp.vec3d, device=dev)
    f = wp.array(gravity.kernel_params()[0], dtype=wp.vec3d, device=dev)
    params = springs.kernel_params()  # mslab's batch order without its gap springs: the same sums
    bi, bj, bk, brest = (np.delete(a, params[10]) for a in params[:4])
    i = wp.array(bi.astype(np.int32), dtype=wp.int32, device=dev)
    j = wp.array(bj.astype(np.int32), dtype=wp.int32, device=dev)
    k = wp.array(bk, dtype=f64, device=dev)
    rest = wp.array(brest, dtype=f64, device=dev)
    im = wp.array(inv_mass, dtype=f64, device=dev)
    m, npart = springs.i.size, x0.shape[0]

    def step(count: int) -> None:
        for _ in range(count):
            wp.launch(spring_forces, dim=m, inputs=[x, i, j, k, rest, f], device=dev)
            wp.launch(integrate, dim=npart, inputs=[x, v, f, fg, im, f64(dt)], device=dev)
        wp.synchronize_device(dev)

    return step, (lambda: (x.numpy(), v.numpy()))


def mslab_stepper(scene, x0, v0, dt: float, threads: int | None = None):
    """``step(n)`` advancing mslab's compiled symplectic Euler loop by ``n`` steps, and its state."""
    import mslab
    from mslab import fast, jit
    from mslab.state import State

    runner = fast.stepper(scene.system, mslab.get_method("symplectic_euler"), "numba")
    state = {"s": State(x0.copy(), v0.copy(), (), 0.0), "step": 0}
    saved = np.empty(0, dtype=np.int64)
    buf = np.empty((0,) + x0.shape)

    def step(count: int) -> None:
        with jit.threads(threads):
            done, _, new, ok = runner.advance(state["s"], dt, state["step"], state["step"] + count, saved, 0,
                                              buf, buf, np.empty(0), 1e12)
        if not ok:
            raise FloatingPointError("mslab's cloth blew up")
        state["s"], state["step"] = new, done

    return step, (lambda: (state["s"].x, state["s"].v)), runner


def _floor_kernel():
    from numba import njit

    @njit(cache=False, error_model="numpy")
    def floor(a, out):
        for q in range(a.shape[0]):
            out[q] = 1.0 / np.sqrt(a[q])

    return floor


def kernel_limit(runner, x, v, repeats: int) -> dict:
    """The spring kernel alone against one square root and one division per spring, interleaved.

    Each repeat times the arithmetic floor (``out[q] = 1 / sqrt(a[q])`` over as many numbers
    as springs: the machine's throughput for the two operations) and then mslab's compiled
    spring kernel on one thread, back to back in CPU time; the ratio is taken per repeat.
    """
    from mslab import jit

    mod, params, kernels = runner.model.module, runner.model.params, runner.model.kernels
    n = next(q for q, kern in enumerate(kernels) if kern.__name__ == "spring_kernel")
    kern = getattr(mod, f"_k{n}")
    m = params[n][0].size - params[n][10].size  # springs (not gap springs)
    x, v = (np.ascontiguousarray(a.T).T for a in (x, v))  # coordinate-major, as the loops hand them
    f = np.zeros_like(x)
    floor = _floor_kernel()
    a = np.random.default_rng(0).uniform(0.5, 2.0, m)
    out = np.empty_like(a)
    floor(a, out)
    with jit.threads(1):
        kern(x, v, f, *params[n])
        number = max(1, int(0.05 / max(1e-7, _once(lambda: kern(x, v, f, *params[n])))))
        t_floor, t_spring = [], []
        for _ in range(repeats):
            t = time.process_time()
            for _ in range(number):
                floor(a, out)
            t_floor.append((time.process_time() - t) / number)
            t = time.process_time()
            for _ in range(number):
                kern(x, v, f, *params[n])
            t_spring.append((time.process_time() - t) / number)
    ratios = [ts / tf for tf, ts in zip(t_floor, t_spring, strict=True)]
    return {"floor_ns_per_spring": 1e9 * statistics.median(t_floor) / m,
            "spring_kernel_ns_per_spring": 1e9 * statistics.median(t_spring) / m,
            "ratio_median": statistics.median(ratios), "ratio_min": min(ratios), "ratio_max": max(ratios)}


def _once(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def compare(wp, n: int, repeats: int, dt: float = 1e-5) -> dict:
    """One cloth size: agreement, interleaved step times (mslab on 1 and all threads), the kernel's limit."""
    from mslab.jit import numba

    scene, x0, v0, springs, gravity = build_cloth(n)
    inv_mass = np.ascontiguousarray(scene.system.inv_mass)
    w_step, w_state = warp_stepper(wp, x0, v0, springs, gravity, inv_mass, dt)
    cores = numba().config.NUMBA_NUM_THREADS
    steppers = {"warp": (w_step, w_state)}
    for threads in sorted({1, cores}):
        m_step, m_state, runner = mslab_stepper(scene, x0, v0, dt, threads)
        steppers[f"mslab_{threads}"] = (m_step, m_state)
    m = springs.i.size
    for fn, _ in steppers.values():
        fn(2)  # warm-up: compile (Warp) and load or compile (mslab) outside the timings
    per = max(_once(lambda fn=fn: fn(3)) for fn, _ in steppers.values()) / 3  # all 5 steps ahead of x0
    block = max(5, int(0.2 / per))
    wall = {name: [] for name in steppers}
    cpu = {name: [] for name in steppers}
    for _ in range(repeats):
        for name, (fn, _) in steppers.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn(block)
            wall[name].append((time.perf_counter() - t0) / block)
            cpu[name].append((time.process_time() - c0) / block)
    xw, vw = w_state()
    out = {"n": n, "n_particles": int(x0.shape[0]), "n_springs": int(m), "dt": dt, "threads": cores,
           "steps_per_block": block, "repeats": repeats, "steps_compared": 5 + repeats * block}
    for name, (_, state) in steppers.items():
        xm, vm = state()
        if name != "warp" and not (np.array_equal(xm, xw) and np.array_equal(vm, vw)):
            dx = float(np.max(np.abs(xw - xm)))
            raise AssertionError(f"mslab ({name}) and Warp differ on the {n}x{n} cloth: |dx| = {dx:.3g}")
    out["bitwise_equal"] = True
    out["kernel_limit"] = kernel_limit(runner, xw, vw, repeats)
    for name in steppers:
        if name == "warp":
            continue
        clocks = (("wall", wall), ("cpu", cpu)) if name == "mslab_1" else (("wall", wall),)
        for clock, times in clocks:
            ratios = [b / a for a, b in zip(times["warp"], times[name], strict=True)]
            out[f"{name}_{clock}"] = {
                "warp_step_s": statistics.median(times["warp"]),
                "mslab_step_s": statistics.median(times[name]),
                "ratio_median": statistics.median(ratios), "ratio_min": min(ratios), "ratio_max": max(ratios),
                "warp_ns_per_spring": 1e9 * statistics.median(times["warp"]) / m,
                "mslab_ns_per_spring": 1e9 * statistics.median(times[name]) / m}
    return out


def run(quick: bool = False, sizes=(100, 300)) -> dict:
    """The whole comparison; ``{"skipped": reason}`` where Warp does not install."""
    wp, reason = load_warp()
    doc = {"machine": machine(), "quick": quick}
    if wp is None:
        doc["skipped"] = reason
        return doc
    doc["machine"]["warp"] = wp.__version__
    repeats = 5 if quick else 11
    for n in sizes:
        doc[f"cloth_{n}"] = compare(wp, n, repeats)
    doc["load_average"] = list(os.getloadavg())
    return doc


def table(doc: dict) -> str:
    """The comparison as Markdown (or the reason it was skipped)."""
    if "skipped" in doc:
        return f"Warp comparison skipped: {doc['skipped']}."
    rows = ["| cloth | springs | mslab threads, clock | Warp step (ms) | mslab step (ms) | mslab / Warp: "
            "median (min-max) | ns/spring Warp / mslab |", "|---|---|---|---|---|---|---|"]
    keys = sorted((k for k in doc if k.startswith("cloth_")), key=lambda k: doc[k]["n"])
    for key in keys:
        c = doc[key]
        for run in sorted(k for k in c if k.startswith("mslab_")):
            t = c[run]
            threads, clock = run.split("_")[1:]
            rows.append(
                f"| {c['n']}x{c['n']} | {c['n_springs']} | {threads}, {clock} | {1e3 * t['warp_step_s']:.3g} "
                f"| {1e3 * t['mslab_step_s']:.3g} | {t['ratio_median']:.3f} ({t['ratio_min']:.3f}-"
                f"{t['ratio_max']:.3f}) | {t['warp_ns_per_spring']:.3g} / {t['mslab_ns_per_spring']:.3g} |")
    rows += ["", "| cloth | spring kernel, one thread | one square root + one division (vectorised) "
             "| kernel / that floor: median (min-max) | mslab = Warp bitwise |", "|---|---|---|---|---|"]
    for key in keys:
        c, lim = doc[key], doc[key]["kernel_limit"]
        rows.append(f"| {c['n']}x{c['n']} | {lim['spring_kernel_ns_per_spring']:.3g} ns/spring | "
                    f"{lim['floor_ns_per_spring']:.3g} ns/spring | {lim['ratio_median']:.2f} "
                    f"({lim['ratio_min']:.2f}-{lim['ratio_max']:.2f}) | {c['bitwise_equal']} |")
    return "\n".join(rows)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    parser.add_argument("--sizes", type=int, nargs="*", default=[100, 300])
    args = parser.parse_args()
    doc = run(args.quick, tuple(args.sizes))
    (HERE / "warp_results.json").write_text(json.dumps(doc, indent=2) + "\n")
    print(table(doc))
    if "load_average" in doc:
        load = ", ".join(f"{x:.2f}" for x in doc["load_average"])
        print(f"load average {load} on {doc['machine']['cores']} cores; {doc['machine']['cpu']}, "
              f"warp {doc['machine'].get('warp')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
