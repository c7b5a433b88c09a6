"""Frame-by-frame stepping through the public API against NVIDIA Warp's CPU backend (issue 26).

Usage (from a checkout; ``warp-lang`` is the optional ``bench`` extra, never a runtime need)::

    python benchmarks/frame_loop.py            # 32^2, 64^2, 128^2 cloths + the chunked 300^2 run
    python benchmarks/frame_loop.py --quick    # fewer repeats

The loop a graphics user writes: one call per frame of 16 symplectic-Euler substeps at 60
frames per second (``dt = 1/960``), on a square cloth of ``n x n`` particles of 0.25 kg with
structural, shear and bend springs of stiffness 1000 and damping 10 along each spring, two
pinned corners, gravity 9.81 (``mslab.scenes.generators.cloth``). Compared per frame:

* **mslab**: ``sim = mslab.Simulation(scene, "symplectic_euler", dt)`` with default options,
  then ``sim.advance(16)`` per frame (the first frames, which load the compiled code, are left
  out); also the same 16 steps inside one long call, the loop's own speed;
* **Warp float64**: the same update, the same operations and summation order (springs with
  atomic adds, then an integrate kernel that resets the force to ``m g``), two launches per
  substep, the scene's own arrays; the states must agree with mslab's to 1e-9 after every
  repeat — the ratio compares equal work;
* **Warp float32**: the same kernels in single precision (Warp's usual cloth), reported too.

Timing: wall clock, repeats interleaved (Warp f64, mslab, Warp f32 back to back, so load from
other jobs hits all), the ratio mslab / Warp f64 per repeat and its median with min and max.
Issue 21 item 2 is measured here too: a 300 x 300 cloth advanced in 20 calls of 13 steps
against one call of 260 steps (compiled path), ratio per repeat, median. Results go to
``frame_loop.json``; the machine and the load average are recorded.
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
from benchmarks.warp_cloth import load_warp  # noqa: E402

SUBSTEPS = 16
DT = 1.0 / 60.0 / SUBSTEPS


def frame_cloth(n: int):
    """The issue's cloth: n x n particles of 0.25 kg (stable at dt = 1/960), k = 1000, c = 10 per spring."""
    from mslab.scenes.generators import cloth

    return cloth(n, n, size=0.02 * (n - 1), mass=0.25 * n * n, structural=1000.0, shear=1000.0, bend=1000.0,
                 damping=10.0, gravity=9.81)


def warp_frames(wp, scene, dtype: str):
    """``frame(count)`` advancing Warp's copy of the cloth by ``count`` frames, and ``state()``."""
    from mslab.effects import Gravity, Springs

    system = scene.system
    springs = next(e for e in system.effects if type(e) is Springs)
    gravity = next(e for e in system.effects if type(e) is Gravity)
    real, vec = (wp.float64, wp.vec3d) if dtype == "float64" else (wp.float32, wp.vec3f)
    np_real = np.float64 if dtype == "float64" else np.float32

    @wp.kernel
    def spring_forces(x: wp.array(dtype=vec), v: wp.array(dtype=vec), i: wp.array(dtype=wp.int32),
                      j: wp.array(dtype=wp.int32), k: wp.array(dtype=real), rest: wp.array(dtype=real),
                      c: wp.array(dtype=real), f: wp.array(dtype=vec)):
        q = wp.tid()
        a = i[q]
        b = j[q]
        d = x[a] - x[b]
        length = wp.length(d)
        inv_l = real(0.0)
        if length > real(0.0):
            inv_l = real(1.0) / length
        rate = inv_l * wp.dot(d, v[a] - v[b])
        s = k[q] * (rest[q] * inv_l - real(1.0)) - c[q] * rate * inv_l
        fq = s * d
        wp.atomic_add(f, a, fq)
        wp.atomic_sub(f, b, fq)

    @wp.kernel
    def integrate(x: wp.array(dtype=vec), v: wp.array(dtype=vec), f: wp.array(dtype=vec),
                  fg: wp.array(dtype=vec), inv_m: wp.array(dtype=real), h: real):
        p = wp.tid()
        vn = v[p] + h * (inv_m[p] * f[p])
        v[p] = vn
        x[p] = x[p] + h * vn
        f[p] = fg[p]

    dev = "cpu"
    fg0 = gravity.kernel_params()[0].astype(np_real)
    x = wp.array(scene.state0.x.astype(np_real), dtype=vec, device=dev)
    v = wp.array(scene.state0.v.astype(np_real), dtype=vec, device=dev)
    fg, f = wp.array(fg0, dtype=vec, device=dev), wp.array(fg0, dtype=vec, device=dev)
    i = wp.array(springs.i.astype(np.int32), dtype=wp.int32, device=dev)
    j = wp.array(springs.j.astype(np.int32), dtype=wp.int32, device=dev)
    k = wp.array(springs.stiffness.astype(np_real), dtype=real, device=dev)
    rest = wp.array(springs.rest_length.astype(np_real), dtype=real, device=dev)
    c = wp.array(springs.damping.astype(np_real), dtype=real, device=dev)
    im = wp.array(system.inv_mass.astype(np_real), dtype=real, device=dev)
    m, npart, h = springs.i.size, system.n_particles, real(DT)

    def frame(count: int) -> None:
        for _ in range(count * SUBSTEPS):
            wp.launch(spring_forces, dim=m, inputs=[x, v, i, j, k, rest, c, f], device=dev)
            wp.launch(integrate, dim=npart, inputs=[x, v, f, fg, im, h], device=dev)
        wp.synchronize_device(dev)

    return frame, (lambda: (x.numpy().astype(np.float64), v.numpy().astype(np.float64)))


def _timed(fn, *args) -> float:
    t = time.perf_counter()
    fn(*args)
    return time.perf_counter() - t


def compare(wp, n: int, repeats: int, frames: int) -> dict:
    """Per-frame seconds of mslab (public API, defaults), Warp f64 and f32; ratios per repeat."""
    import mslab
    from mslab.effects import Springs

    scene = frame_cloth(n)
    sim = mslab.Simulation(scene, "symplectic_euler", dt=DT)
    sim1 = mslab.Simulation(scene, "symplectic_euler", dt=DT, threads=1)  # the same, on one thread

    def mslab_frames(count: int) -> None:
        for _ in range(count):
            sim.advance(SUBSTEPS)

    def mslab_frames_1(count: int) -> None:
        for _ in range(count):
            sim1.advance(SUBSTEPS)

    w64, state64 = warp_frames(wp, scene, "float64")
    w32, _ = warp_frames(wp, scene, "float32")
    for fn in (w64, w32, mslab_frames, mslab_frames_1):
        fn(2)  # warm-up: Warp compiles, mslab decides its backend and loads the compiled loop
    long_run = mslab.Simulation(scene, "symplectic_euler", dt=DT)
    long_run.advance(SUBSTEPS)
    rows = {"warp64": [], "mslab": [], "warp32": [], "mslab_one_call": [], "mslab_1_thread": []}
    worst = 0.0
    for _ in range(repeats):
        rows["warp64"].append(_timed(w64, frames) / frames)
        rows["mslab"].append(_timed(mslab_frames, frames) / frames)
        rows["warp32"].append(_timed(w32, frames) / frames)
        rows["mslab_one_call"].append(_timed(long_run.advance, SUBSTEPS * frames) / frames)
        rows["mslab_1_thread"].append(_timed(mslab_frames_1, frames) / frames)
        wx, wv = state64()
        state = sim.state
        size = max(1.0, float(np.abs(state.x).max()))
        worst = max(worst, float(np.abs(wx - state.x).max()) / size)
        if worst > 1e-9:
            raise RuntimeError(f"mslab and Warp float64 disagree by {worst:.3g} at {n}x{n}")
        if not np.array_equal(sim1.state.x, sim.state.x):
            raise RuntimeError("mslab on one thread and on all differ")
    ratios = [m / w for m, w in zip(rows["mslab"], rows["warp64"], strict=True)]
    ratios_1 = [m / w for m, w in zip(rows["mslab_1_thread"], rows["warp64"], strict=True)]
    med = {key: statistics.median(vals) for key, vals in rows.items()}
    return {"n": n, "n_particles": scene.system.n_particles,
            "n_springs": int(sum(e.i.size for e in scene.system.effects if isinstance(e, Springs))),
            "frames_per_repeat": frames, "repeats": repeats, "compiled": sim.compiled,
            "max_rel_difference_x": worst,
            "frame_s": med, "ratio_mslab_warp64_median": statistics.median(ratios),
            "ratio_min": min(ratios), "ratio_max": max(ratios),
            "threads": _threads_used(sim),
            "ratio_1_thread_warp64_median": statistics.median(ratios_1),
            "ratio_1_thread_min": min(ratios_1), "ratio_1_thread_max": max(ratios_1),
            "ratio_mslab_warp32": med["mslab"] / med["warp32"],
            "ratio_frame_vs_one_call": med["mslab"] / med["mslab_one_call"]}


def _threads_used(sim) -> int:
    """Threads the spring loop of ``sim`` uses: 1 for a scene of one batch (below the threshold)."""
    import mslab
    from mslab.effects import Springs

    springs = next(e for e in sim.system.effects if isinstance(e, Springs))
    one_batch = len(springs.kernel_params()[8]) == 2
    return 1 if one_batch else (sim.threads or mslab.jit.numba().config.NUMBA_NUM_THREADS)


def chunked_vs_one_call(repeats: int, n: int = 300) -> dict:
    """Issue 21 item 2: 20 calls of 13 steps against one call of 260 steps, compiled, 300 x 300."""
    import mslab

    scene = frame_cloth(n)
    chunked = mslab.Simulation(scene, "symplectic_euler", dt=DT, backend="numba")
    whole = mslab.Simulation(scene, "symplectic_euler", dt=DT, backend="numba")
    chunked.advance(1)
    whole.advance(1)
    ratios, t_chunk, t_one = [], [], []
    for _ in range(repeats):
        a = _timed(lambda: [chunked.advance(13) for _ in range(20)])
        b = _timed(whole.advance, 260)
        ratios.append(a / b)
        t_chunk.append(a)
        t_one.append(b)
    assert np.array_equal(chunked.state.x, whole.state.x)  # the same run, bitwise
    return {"n": n, "repeats": repeats, "chunked_s": statistics.median(t_chunk),
            "one_call_s": statistics.median(t_one), "ratio_median": statistics.median(ratios),
            "ratio_min": min(ratios), "ratio_max": max(ratios)}


def table(doc: dict) -> str:
    lines = ["| cloth | springs | mslab per frame (threads) | one long call | Warp f64 | Warp f32 "
             "| mslab / Warp f64 (median, min–max) | mslab / Warp f32 | mslab on 1 thread / Warp f64 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for key in sorted(k for k in doc if k.startswith("cloth_")):
        r = doc[key]
        f = r["frame_s"]
        lines.append(f"| {r['n']}² | {r['n_springs']:,} | {1e3 * f['mslab']:.2f} ms ({r['threads']}) | "
                     f"{1e3 * f['mslab_one_call']:.2f} ms | {1e3 * f['warp64']:.2f} ms | "
                     f"{1e3 * f['warp32']:.2f} ms | {r['ratio_mslab_warp64_median']:.2f} "
                     f"({r['ratio_min']:.2f}–{r['ratio_max']:.2f}) | {r['ratio_mslab_warp32']:.2f} | "
                     f"{r['ratio_1_thread_warp64_median']:.2f} ({r['ratio_1_thread_min']:.2f}–"
                     f"{r['ratio_1_thread_max']:.2f}) |")
    c = doc.get("chunked_300")
    if c:
        lines.append(f"\n300² cloth, 20 calls of 13 steps / one call of 260 steps: {c['ratio_median']:.3f} "
                     f"(min {c['ratio_min']:.3f}, max {c['ratio_max']:.3f}; {c['chunked_s']:.3f} s / "
                     f"{c['one_call_s']:.3f} s)")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--sizes", type=int, nargs="*", default=[32, 64, 128])
    args = parser.parse_args()
    wp, reason = load_warp()
    if wp is None:
        print(f"frame_loop: {reason}", file=sys.stderr)
        return 2
    doc = {"machine": {**machine(), "warp": wp.__version__}, "quick": args.quick,
           "load_average_before": list(os.getloadavg())}
    repeats = 5 if args.quick else 11
    for n in args.sizes:
        doc[f"cloth_{n}"] = compare(wp, n, repeats, frames=max(4, 4096 // n))
    doc["chunked_300"] = chunked_vs_one_call(3 if args.quick else 7)
    doc["load_average_after"] = list(os.getloadavg())
    (HERE / "frame_loop.json").write_text(json.dumps(doc, indent=2) + "\n")
    print(table(doc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
