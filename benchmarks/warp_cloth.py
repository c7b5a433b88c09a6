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
* **bandwidth**: the spring kernel alone (mslab's ``spring_kernel`` as compiled by
  ``mslab.fast``, with the parameters it is given there: uint32 indices), in bytes per
  spring as issue 14 counts them (two int64 indices,
  stiffness and rest length, read ``x_i, x_j``, write ``f_i, f_j``: 128 bytes), against a
  STREAM-like copy (``b[i] = a[i]`` over 2 x 128 MiB, 16 bytes per element) measured in
  the same run, interleaved (copy, then kernel, per repeat, in CPU time; the share per
  repeat, its median with min and max). Everything single-threaded: Warp's CPU backend
  runs a launch on one thread, and so does mslab's loop.
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

#: bytes per spring as issue 14 counts them (see the module docstring)
BYTES_PER_SPRING = 128


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
        s = -k[q]
        if length > f64(0.0):
            s = k[q] * (rest[q] / length - f64(1.0))
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
    i = wp.array(springs.i.astype(np.int32), dtype=wp.int32, device=dev)
    j = wp.array(springs.j.astype(np.int32), dtype=wp.int32, device=dev)
    k = wp.array(springs.stiffness, dtype=f64, device=dev)
    rest = wp.array(springs.rest_length, dtype=f64, device=dev)
    im = wp.array(inv_mass, dtype=f64, device=dev)
    m, npart = springs.i.size, x0.shape[0]

    def step(count: int) -> None:
        for _ in range(count):
            wp.launch(spring_forces, dim=m, inputs=[x, i, j, k, rest, f], device=dev)
            wp.launch(integrate, dim=npart, inputs=[x, v, f, fg, im, f64(dt)], device=dev)
        wp.synchronize_device(dev)

    return step, (lambda: (x.numpy(), v.numpy()))


def mslab_stepper(scene, x0, v0, dt: float):
    """``step(n)`` advancing mslab's compiled symplectic Euler loop by ``n`` steps, and its state."""
    import mslab
    from mslab import fast
    from mslab.state import State

    runner = fast.stepper(scene.system, mslab.get_method("symplectic_euler"), "numba")
    state = {"s": State(x0.copy(), v0.copy(), (), 0.0), "step": 0}
    saved = np.empty(0, dtype=np.int64)
    buf = np.empty((0,) + x0.shape)

    def step(count: int) -> None:
        done, _, new, ok = runner.advance(state["s"], dt, state["step"], state["step"] + count, saved, 0,
                                          buf, buf, np.empty(0), 1e12)
        if not ok:
            raise FloatingPointError("mslab's cloth blew up")
        state["s"], state["step"] = new, done

    return step, (lambda: (state["s"].x, state["s"].v)), runner


def _copy_kernel():
    from numba import njit

    @njit(cache=False)
    def copy(a, b):
        for p in range(a.shape[0]):
            b[p] = a[p]

    return copy


def bandwidth_share(runner, x, v, repeats: int) -> dict:
    """The spring kernel's bytes per second as a share of a STREAM-like copy, interleaved.

    Each repeat times one copy ``b[i] = a[i]`` over 2 x 128 MiB (16 bytes per element, far
    beyond the caches) and then mslab's compiled spring kernel alone (forces into a buffer,
    128 bytes per spring), back to back in CPU time; the share is taken per repeat.
    """
    mod, params, kernels = runner.model.module, runner.model.params, runner.model.kernels
    n = next(q for q, kern in enumerate(kernels) if kern.__name__ == "spring_kernel")
    kern = getattr(mod, f"_k{n}")
    m = params[n][0].size
    f = np.zeros_like(x)
    copy = _copy_kernel()
    a = np.random.default_rng(0).random(2**24)
    b = np.empty_like(a)
    copy(a, b)
    kern(x, v, f, *params[n])
    number = max(1, int(0.05 / max(1e-7, _once(lambda: kern(x, v, f, *params[n])))))
    t_copy, t_spring = [], []
    for _ in range(repeats):
        t = time.process_time()
        copy(a, b)
        t_copy.append(time.process_time() - t)
        t = time.process_time()
        for _ in range(number):
            kern(x, v, f, *params[n])
        t_spring.append((time.process_time() - t) / number)
    shares = [(BYTES_PER_SPRING * m / ts) / (16 * a.size / tc)
              for tc, ts in zip(t_copy, t_spring, strict=True)]
    return {"copy_bytes_per_s": 16 * a.size / statistics.median(t_copy),
            "spring_kernel_ns_per_spring": 1e9 * statistics.median(t_spring) / m,
            "spring_kernel_bytes_per_s": BYTES_PER_SPRING * m / statistics.median(t_spring),
            "share_median": statistics.median(shares), "share_min": min(shares), "share_max": max(shares)}


def _once(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def compare(wp, n: int, repeats: int, dt: float = 1e-5) -> dict:
    """One cloth size: agreement, interleaved step times, the spring kernel's share of bandwidth."""
    scene, x0, v0, springs, gravity = build_cloth(n)
    inv_mass = np.ascontiguousarray(scene.system.inv_mass)
    w_step, w_state = warp_stepper(wp, x0, v0, springs, gravity, inv_mass, dt)
    m_step, m_state, runner = mslab_stepper(scene, x0, v0, dt)
    m = springs.i.size
    # steps per timed block: about 0.2 s of work
    w_step(2)
    m_step(2)  # warm-up: compile (Warp) and load or compile (mslab) outside the timings
    per = max(_once(lambda: w_step(3)), _once(lambda: m_step(3))) / 3  # both 5 steps ahead of x0
    block = max(5, int(0.2 / per))
    wall = {"warp": [], "mslab": []}
    cpu = {"warp": [], "mslab": []}
    for _ in range(repeats):
        for name, fn in (("warp", w_step), ("mslab", m_step)):
            t0, c0 = time.perf_counter(), time.process_time()
            fn(block)
            wall[name].append((time.perf_counter() - t0) / block)
            cpu[name].append((time.process_time() - c0) / block)
    xw, vw = w_state()
    xm, vm = m_state()
    scale = max(1.0, float(np.max(np.abs(xm))))
    dx = float(np.max(np.abs(xw - xm))) / scale
    dv = float(np.max(np.abs(vw - vm))) / max(1.0, float(np.max(np.abs(vm))))
    if not (dx <= 1e-12 and dv <= 1e-12):
        raise AssertionError(f"mslab and Warp disagree on the {n}x{n} cloth: "
                             f"|dx| = {dx:.3g}, |dv| = {dv:.3g}")
    share = bandwidth_share(runner, xm, vm, repeats)
    out = {"n": n, "n_particles": int(x0.shape[0]), "n_springs": int(m), "dt": dt,
           "steps_per_block": block, "repeats": repeats, "steps_compared": 5 + repeats * block,
           "max_rel_difference_x": dx, "max_rel_difference_v": dv, "bandwidth": share}
    for clock, times in (("wall", wall), ("cpu", cpu)):
        ratios = [b / a for a, b in zip(times["warp"], times["mslab"], strict=True)]
        out[clock] = {"warp_step_s": statistics.median(times["warp"]),
                      "mslab_step_s": statistics.median(times["mslab"]),
                      "ratio_median": statistics.median(ratios), "ratio_min": min(ratios),
                      "ratio_max": max(ratios),
                      "warp_ns_per_spring": 1e9 * statistics.median(times["warp"]) / m,
                      "mslab_ns_per_spring": 1e9 * statistics.median(times["mslab"]) / m}
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
    rows = ["| cloth | springs | clock | Warp step (ms) | mslab step (ms) | mslab / Warp: median (min-max) "
            "| ns/spring Warp / mslab |", "|---|---|---|---|---|---|---|"]
    keys = sorted((k for k in doc if k.startswith("cloth_")), key=lambda k: doc[k]["n"])
    for key in keys:
        c = doc[key]
        for clock in ("cpu", "wall"):
            t = c[clock]
            rows.append(
                f"| {c['n']}x{c['n']} | {c['n_springs']} | {clock} | {1e3 * t['warp_step_s']:.3g} | "
                f"{1e3 * t['mslab_step_s']:.3g} | {t['ratio_median']:.3f} ({t['ratio_min']:.3f}-"
                f"{t['ratio_max']:.3f}) | {t['warp_ns_per_spring']:.3g} / {t['mslab_ns_per_spring']:.3g} |")
    rows += ["", "| cloth | copy bandwidth | spring kernel alone | at 128 B/spring | share of copy "
             "bandwidth: median (min-max) | max rel. difference mslab - Warp |", "|---|---|---|---|---|---|"]
    for key in keys:
        c, bw = doc[key], doc[key]["bandwidth"]
        rows.append(f"| {c['n']}x{c['n']} | {bw['copy_bytes_per_s'] / 1e9:.1f} GB/s | "
                    f"{bw['spring_kernel_ns_per_spring']:.3g} ns/spring | "
                    f"{bw['spring_kernel_bytes_per_s'] / 1e9:.1f} GB/s | {100 * bw['share_median']:.0f} % "
                    f"({100 * bw['share_min']:.0f}-{100 * bw['share_max']:.0f} %) | "
                    f"{max(c['max_rel_difference_x'], c['max_rel_difference_v']):.1e} |")
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
