"""fast_mass_spring at the cost of its linear algebra (issue 22 item 3): mslab against a plain reference.

Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/fast_mass_spring.py [--quick]

Measures, in one run with the machine recorded (ratios compare timings of this run, repeats
interleaved, medians):

1. the steady frame (h = 1/30, 10 iterations) on the 81 x 81 cloth: mslab's
   ``fast_mass_spring`` against :class:`PlainFastMassSpring`, a plain numba + CHOLMOD
   local/global written here (numba local step, numpy right-hand side, one CHOLMOD solve of
   the three coordinates per iteration), both stepping from the same states; the time of one
   CHOLMOD solve alone and the solves' share of the reference's frame (timed inside frames);
   mslab on one thread too; the setup (matrix, factorisation, Chebyshev's spectral radius) of both,
   timed on its own and not charged to the frame, with mslab's counters;
2. distance from implicit Euler's step against time: ``max|x - x_IE| / max|x_IE - x_n|`` for
   5 to 40 plain and Chebyshev-accelerated (Wang 2015; mslab's one-sided default and Wang's
   own form) iterations from the same state, with each variant's frame time.

Frames are timed by the wall clock (mslab's iterations run on every core; the CPU times of
the steady frame are recorded too), setup by CPU time (:func:`timed`). BLAS single-threaded.

Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp

import mslab
from mslab.integrators.families.local_global import LocalGlobal, global_step
from mslab.state import State
from mslab.threads import single_threaded_blas

HERE = Path(__file__).resolve().parent
try:
    from implicit_cloth import machine, scaled_cloth
except ImportError:  # run as a module
    from benchmarks.implicit_cloth import machine, scaled_cloth


# -- the reference: a plain numba + CHOLMOD local/global -------------------------------------------
@numba.njit(cache=True)
def _local(x, i, j, k, rest, out):
    out[:] = 0.0
    for q in range(i.size):
        a, b = i[q], j[q]
        d0, d1, d2 = x[a, 0] - x[b, 0], x[a, 1] - x[b, 1], x[a, 2] - x[b, 2]
        length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if length > 0.0:
            s = k[q] * rest[q] / length
            out[a, 0] += s * d0
            out[a, 1] += s * d1
            out[a, 2] += s * d2
            out[b, 0] -= s * d0
            out[b, 1] -= s * d1
            out[b, 2] -= s * d2


class PlainFastMassSpring:
    """Liu et al. 2013 as one would write it: numba local step, CHOLMOD factor kept, numpy glue."""

    def __init__(self, system, dt):
        import cvxopt
        import cvxopt.cholmod

        self.cvxopt = cvxopt
        e = next(e for e in system.effects if e.name == "springs")
        self.i, self.j, self.k, self.rest = e.i, e.j, e.stiffness, e.rest_length
        gamma = sum(e.gamma for e in system.effects if e.name == "damping")
        self.gravity = sum(e.constant_force() for e in system.effects if e.name == "gravity")
        n, i, j, k = system.n_particles, self.i, self.j, self.k
        lap = sp.coo_matrix((np.r_[k, k, -k, -k], (np.r_[i, j, i, j], np.r_[i, j, j, i])),
                            shape=(n, n)).tocsr()
        self.free, self.pinned = ~system.pinned, system.pinned
        self.lap_fp = lap[self.free][:, self.pinned]
        Q = sp.tril(sp.diags(system.mass[self.free] + dt * gamma)
                    + dt * dt * lap[self.free][:, self.free]).tocoo()
        A = cvxopt.spmatrix(Q.data, Q.row.astype(np.int64), Q.col.astype(np.int64), Q.shape)
        self.F = cvxopt.cholmod.symbolic(A)
        cvxopt.cholmod.numeric(A, self.F)
        self.system, self.dt, self.gamma = system, dt, gamma
        self.jd = np.zeros((n, 3))

    def step(self, state, iterations=10):
        s, dt, free = self.system, self.dt, self.free
        xn, vn = state.x, state.v
        y = xn + dt * vn
        base = (s.mass[free, None] * y[free] + dt * self.gamma * xn[free]
                - dt * dt * (self.lap_fp @ y[self.pinned]))
        x = y.copy()
        for _ in range(iterations):
            _local(x, self.i, self.j, self.k, self.rest, self.jd)
            B = self.cvxopt.matrix(base + dt * dt * (self.jd[free] + self.gravity[free]))
            self.cvxopt.cholmod.solve(self.F, B)
            x[free] = np.array(B)
        return State(x, (x - xn) / dt)


# -- measurements ------------------------------------------------------------------------------------
#: frames stepped back to back per code and repeat (steady_frame)
BLOCK = 5

def timed(f, *args, **kw):
    """Return the CPU time of ``f(*args)`` (this process, all its threads) and its result.

    For the single-threaded parts (setup, the distance rows); the steady frame is timed by
    the wall clock (mslab's iterations run on every core).
    """
    t = time.process_time()
    out = f(*args, **kw)
    return time.process_time() - t, out


def timed_wall(f, *args, **kw):
    t, c = time.perf_counter(), time.process_time()
    out = f(*args, **kw)
    return time.process_time() - c, time.perf_counter() - t, out


def setup_times(n: int, dt: float) -> dict:
    """Setup on a fresh scene (compiled code warm from the disk cache), timed apart from any frame.

    mslab: the global matrix and its factorisation (:func:`global_step`, counted); the
    reference: the same in its own code; Chebyshev's spectral radius estimate: its first step
    minus a second one from the same state.
    """
    scene = scaled_cloth(n)
    s = scene.system
    fms = mslab.get_method("fast_mass_spring")
    before = s.counters.snapshot()
    t_build, _ = timed(global_step, s, dt)
    counters = s.counters.since(before)
    t_ref, _ = timed(PlainFastMassSpring, s, dt)
    cheb = LocalGlobal(chebyshev=True)
    before = s.counters.snapshot()
    t_rho, _ = timed(cheb.step, s, scene.state0, dt)
    t_frame, _ = timed(cheb.step, s, scene.state0, dt)
    rho_work = s.counters.since(before)
    fms.step(s, scene.state0, dt)
    return {"mslab_setup_ms": 1e3 * t_build, "mslab_setup_counters": counters,
            "reference_setup_ms": 1e3 * t_ref,
            "chebyshev_rho_estimate_ms": 1e3 * (t_rho - t_frame), "rho": global_step(s, dt).rho,
            "chebyshev_first_two_steps_counters": rho_work}


def steady_frame(n: int, repeats: int, dt: float = 1 / 30) -> dict:
    """mslab's frame (default threads, and on one thread) against the reference's, interleaved.

    Wall times (mslab's iterations run on every core: CPU time would add the threads' times;
    it is recorded too). Each repeat steps each code :data:`BLOCK` frames back to back from
    the same state (a simulation's frames follow each other; a frame right after another
    program ran pays for waking the second core: on this virtual machine up to a few ms),
    codes in an order that rotates, and keeps each block's median frame; ratios are per
    repeat, then the median.
    """
    from mslab.jit import threads

    scene = scaled_cloth(n)
    s = scene.system
    fms = mslab.get_method("fast_mass_spring")
    ref = PlainFastMassSpring(s, dt)
    state = scene.state0
    for _ in range(3):  # compile, factor: setup, not timed here
        state = fms.step(s, state, dt)
        ref.step(state)
        with threads(1):
            fms.step(s, state, dt)
    g = global_step(s, dt)
    b = np.asfortranarray(np.random.default_rng(0).standard_normal((int(g.free.sum()), 3)))
    B = ref.cvxopt.matrix(b)

    def one_thread(*args):
        with threads(1):
            return fms.step(*args)

    runs = {"mslab": lambda st: fms.step(s, st, dt), "mslab_one_thread": lambda st: one_thread(s, st, dt),
            "reference": ref.step}
    wall = {k: [] for k in runs}
    cpu = {k: [] for k in runs}
    t_solve, t_ref_solve, diff = [], [], []
    before = s.counters.snapshot()
    names = list(runs)
    for r in range(repeats):
        out = {}
        for k in names[r % 3:] + names[:r % 3]:  # the order rotates
            frames = []
            for _ in range(BLOCK):  # frames back to back, as a simulation steps them
                frames.append(timed_wall(runs[k], state))
            c, w, out[k] = sorted(frames, key=lambda f: f[1])[BLOCK // 2]  # the block's median frame
            cpu[k].append(c)
            wall[k].append(w)
        t_solve.append(min(timed_wall(g.factor.solve, b)[1] for _ in range(3)))
        t_ref_solve.append(min(timed_wall(ref.cvxopt.cholmod.solve, ref.F, ref.cvxopt.matrix(B))[1]
                               for _ in range(3)))
        diff.append(float(np.abs(out["mslab"].x - out["reference"].x).max()))
        assert np.array_equal(out["mslab"].x, out["mslab_one_thread"].x)  # any thread count: same bits
        state = out["mslab"]
    work = s.counters.since(before)
    w = {k: np.array(v) for k, v in wall.items()}
    c = {k: np.array(v) for k, v in cpu.items()}
    return {"n": n, "repeats": repeats, "threads": g.factor.bins if hasattr(g.factor, "bins") else 1,
            "solver": type(g.factor).__name__, "compiled_loop": g.loop is not None,
            "wall_frame_ms": {k: 1e3 * float(np.median(v)) for k, v in w.items()},
            "wall_ratio_mslab_over_reference": float(np.median(w["mslab"] / w["reference"])),
            "wall_ratio_min_max": [float(np.min(w["mslab"] / w["reference"])),
                                   float(np.max(w["mslab"] / w["reference"]))],
            "wall_ratio_one_thread_over_reference": float(np.median(w["mslab_one_thread"] / w["reference"])),
            "cpu_frame_ms": {k: 1e3 * float(np.median(v)) for k, v in c.items()},
            "cpu_ratio_mslab_over_reference": float(np.median(c["mslab"] / c["reference"])),
            "solve_ms_mslab_reference": [1e3 * float(np.median(t_solve)),
                                         1e3 * float(np.median(t_ref_solve))],
            "ten_solves_share_of_reference_frame": float(np.median(10 * np.array(t_ref_solve)
                                                                   / w["reference"])),
            "in_frame_solve_share_reference": solve_share(ref, state, max(3, repeats // 4)),
            "max_position_difference": max(diff),
            "counters_per_frame": {k: v / (2 * BLOCK * repeats) for k, v in work.items()}}


def solve_share(ref, state, repeats: int) -> float:
    """Share of the CHOLMOD solves in the reference's frame (CPU time), timed inside extra frames.

    In a frame the solves find the factor partly evicted by the local step: they cost more
    than solves repeated back to back. Timed around ``cvxopt.cholmod.solve``; the median over
    ``repeats`` frames. (mslab's solves run inside its compiled loop: not timed apart.)
    """
    cholmod_solve = ref.cvxopt.cholmod.solve
    spent = [0.0]

    def counting(*args):
        t = time.process_time()
        out = cholmod_solve(*args)
        spent[0] += time.process_time() - t
        return out

    shares = []
    for _ in range(repeats):
        spent[0] = 0.0
        ref.cvxopt.cholmod.solve = counting
        try:
            t, _ = timed(ref.step, state)
        finally:
            ref.cvxopt.cholmod.solve = cholmod_solve
        shares.append(spent[0] / t)
    return float(np.median(shares))


def distance_vs_time(n: int, repeats: int, dt: float = 1 / 30, frames: int = 5) -> dict:
    """Distance from implicit Euler's step vs frame time, plain and Chebyshev, from one state."""
    scene = scaled_cloth(n)
    s = scene.system
    state = scene.state0
    for _ in range(frames):
        state = mslab.get_method("fast_mass_spring").step(s, state, dt)
    exact = mslab.get_method("implicit_euler").step(s, state, dt)
    move = float(np.abs(exact.x - state.x).max())
    variants = {f"{name} {k}": LocalGlobal(iterations=k, **kw) for k in (5, 10, 20, 40)
                for name, kw in (("plain", {}), ("chebyshev (one-sided, default)", {"chebyshev": True}),
                                 ("chebyshev (Wang's form)", {"chebyshev": True, "one_sided": False}))}
    for m in variants.values():
        m.step(s, state, dt)  # the spectral radius estimate: setup
    times = {name: [] for name in variants}
    for _ in range(repeats):  # interleaved
        for name, m in variants.items():
            times[name].append(timed_wall(m.step, s, state, dt)[1])
    rows = [{"variant": name, "frame_ms": 1e3 * float(np.median(times[name])),
             "relative_distance": float(np.abs(m.step(s, state, dt).x - exact.x).max() / move)}
            for name, m in variants.items()]
    return {"n": n, "after_frames": frames, "rho_estimate": global_step(s, dt).rho, "rows": rows}


@single_threaded_blas
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 30 x 30 cloth, few repeats")
    q = parser.parse_args().quick
    n = 30 if q else 81
    out = {"machine_start": machine()}
    out["setup"] = setup_times(n, 1 / 30)
    out["steady_frame"] = steady_frame(n, 5 if q else 21)
    out["distance_vs_time"] = distance_vs_time(n, 2 if q else 5)
    out["machine_end"] = machine()
    print(json.dumps(out, indent=1))
    if not q:
        (HERE / "fast_mass_spring.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
