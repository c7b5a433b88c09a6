"""``Simulation.advance`` with the spring kernel before and after a change, in one process (issue 38).

Usage::

    .venv/bin/python benchmarks/advance_ab.py [--before main] [--repeats 15] [--sizes 64 128 300]
    .venv/bin/python benchmarks/advance_ab.py --loops REV ...

``--loops`` instead compares the stepping loops: the old session's compiled loop is composed from
revision ``REV``'s template ``mslab/fast/loops.py`` (one of coordinate-major memory, commit d3b807e
or later), the spring kernel being this tree's in both.

``--before`` names a git revision whose ``mslab/effects/spring_kernels.py`` is loaded beside
this tree's (from a temporary folder, as the module ``mslab._before_spring_kernels``) and
given to a subclass of :class:`~mslab.effects.Springs` as its kernel; the compiled loop of
:mod:`mslab.fast` composes whichever kernel the effect's class names, so two sessions of the
frame loop's cloth (``benchmarks/frame_loop.py``: k = 1000, c = 10, symplectic Euler at
dt = 1/960, one thread) differ only in the spring kernel. Generated modules and numba's cache
go to a temporary ``MSLAB_CACHE_DIR`` (compiled afresh each run). Per size and precision:
first the end states of both sessions after the warm-up, compared bitwise; then interleaved
repeats, each timing in CPU time back to back the sqrt+div floor of that precision
(``benchmarks/float32.py``), ``advance(16)`` of the old session and of the new. Reported:
ns per spring-step (medians), new / old and new / floor (median, min-max of the per-repeat
ratios), the load average before and after. Written to ``benchmarks/advance_ab.json``. Nothing
here is a test.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.float32 import _ratio, floor_kernel, interleaved  # noqa: E402
from benchmarks.frame_loop import DT, SUBSTEPS, frame_cloth  # noqa: E402
from benchmarks.suite import machine  # noqa: E402


def table_without_gaps(springs) -> tuple:  # noqa: ANN001
    """``springs``' kernel parameters as before gap springs: batches, runs, flags (10 entries)."""
    from mslab.effects.spring_batches import batches, run_flags, segments

    order, ranges, phases = batches(springs.i, springs.j, springs.n)
    i, j = springs.i[order], springs.j[order]
    k, c = springs.stiffness[order], springs.damping[order]
    bounds, run, batch_segments = segments(i, j, ranges)
    return (i, j, k, springs.rest_length[order], c, int(springs.dissipative), bounds,
            run_flags(bounds, run, k, c), batch_segments, phases)


def old_springs(rev: str, folder: Path) -> type:
    """A subclass of ``Springs`` whose compiled kernel is revision ``rev``'s ``spring_kernel``.

    A kernel from before gap springs (no parameter ``gaps``) gets the table it was written for.
    """
    import inspect

    from mslab.effects import Springs

    source = subprocess.run(["git", "show", f"{rev}:mslab/effects/spring_kernels.py"], cwd=HERE.parent,
                            capture_output=True, text=True, check=True).stdout
    path = folder / "_before_spring_kernels.py"
    path.write_text(source)
    name = "mslab._before_spring_kernels"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # the generated loop imports the kernel by its module's name
    spec.loader.exec_module(module)
    members = {"kernel": staticmethod(module.spring_kernel)}
    if "gaps" not in inspect.signature(module.spring_kernel).parameters:
        members["kernel_params"] = lambda self: table_without_gaps(self)
    return type("SpringsBefore", (Springs,), members)


def old_template(rev: str) -> str:
    """Revision ``rev``'s template of the stepping loops (:func:`mslab.fast.compose._template`)."""
    from mslab.fast import compose

    text = subprocess.run(["git", "show", f"{rev}:mslab/fast/loops.py"], cwd=HERE.parent,
                          capture_output=True, text=True, check=True).stdout
    return text[: text.index(compose._MARKER)]


def compare(before: type | str, n: int, dtype: str, repeats: int, sessions: int = 3) -> dict:
    """Bitwise end states, then interleaved CPU times of the floor, the old and the new sessions.

    ``before``: the old session's springs class, or the text of its loops' template. Each
    variant gets ``sessions`` sessions, made alternately (old, new, old, ...): the placement of a
    session's arrays in memory moves its time by up to 15 % (two sessions of the same code,
    measured), so a variant's time per repeat is the mean over its sessions.
    """
    import mslab
    from mslab import jit
    from mslab.effects import Springs
    from mslab.fast import compose

    sims: dict[str, list] = {"old": [], "new": []}
    for _ in range(sessions):
        for name in ("old", "new"):
            scene = frame_cloth(n)
            springs = next(e for e in scene.system.effects if isinstance(e, Springs))
            if name == "old" and not isinstance(before, str):
                springs.__class__ = before
            template, cached = compose._template, dict(compose._modules)
            if name == "old" and isinstance(before, str):  # the loop is composed as the session starts
                compose._template, compose._modules = (lambda: before), {}
            try:
                sims[name].append(mslab.Simulation(scene, "symplectic_euler", dt=DT, backend="numba",
                                                   threads=1, dtype=dtype, check_stability=False))
            finally:
                compose._template, compose._modules = template, cached
    m = springs.i.size
    floor = floor_kernel()
    a = np.random.default_rng(0).uniform(0.5, 2.0, m).astype(dtype)
    out = np.empty_like(a)
    calls = {"floor": lambda: floor(a, out)}
    steps = {"floor": 1}
    for name, group in sims.items():
        for q, sim in enumerate(group):
            calls[f"{name}{q}"], steps[f"{name}{q}"] = (lambda sim=sim: sim.advance(SUBSTEPS)), SUBSTEPS
    with jit.threads(1):
        for call in calls.values():
            call()
        bitwise = all(np.asarray(getattr(sims["old"][0].state, k)).tobytes()
                      == np.asarray(getattr(sims["new"][0].state, k)).tobytes() for k in ("x", "v"))
        load_before = os.getloadavg()
        per_session = interleaved(calls, steps, m, repeats)
    times = {"floor": per_session["floor"]}
    for name in sims:
        rows = [per_session[f"{name}{q}"] for q in range(sessions)]
        times[name] = [statistics.fmean(r[t] for r in rows) for t in range(repeats)]
    return {"n": n, "springs": m, "dtype": dtype, "repeats": repeats, "sessions": sessions,
            "bitwise_after_warm_up": bitwise,
            "ns_per_spring_step": {k: statistics.median(t) for k, t in times.items()},
            "sessions_ns_per_spring_step": {k: statistics.median(t) for k, t in per_session.items()},
            "new_over_old": _ratio(times["new"], times["old"]),
            "new_over_floor": _ratio(times["new"], times["floor"]),
            "old_over_floor": _ratio(times["old"], times["floor"]),
            "load_average_before": load_before, "load_average_after": os.getloadavg()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="main")
    parser.add_argument("--loops", default=None, help="compare the loops' templates instead")
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 300])
    parser.add_argument("--dtypes", nargs="+", default=["float64", "float32"])
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        os.environ["MSLAB_CACHE_DIR"] = folder
        os.environ["NUMBA_CACHE_DIR"] = folder
        before = old_template(args.loops) if args.loops else old_springs(args.before, Path(folder))
        for n in args.sizes:
            for dtype in args.dtypes:
                row = compare(before, n, dtype, args.repeats)
                rows.append(row)
                ns, r, fl = row["ns_per_spring_step"], row["new_over_old"], row["new_over_floor"]
                print("  sessions:", {k: round(t, 2) for k, t in row["sessions_ns_per_spring_step"].items()})
                print(f"{n}x{n} {dtype}: bitwise {row['bitwise_after_warm_up']}, ns/spring-step old "
                      f"{ns['old']:.2f} new {ns['new']:.2f} floor {ns['floor']:.2f}; "
                      f"new/old {r['median']:.3f} "
                      f"({r['min']:.3f}-{r['max']:.3f}); new/floor {fl['median']:.2f} old/floor "
                      f"{row['old_over_floor']['median']:.2f}; load {row['load_average_before'][0]:.2f}-"
                      f"{row['load_average_after'][0]:.2f}", flush=True)
    what = "loops" if args.loops else "spring kernel"
    doc = {"machine": machine(), "before": args.loops or args.before, "what": what, "rows": rows}
    (HERE / "advance_ab.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
