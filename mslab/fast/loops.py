"""The compiled stepping loops: one per method family, generic over the scene's effects.

A *template* of plain functions: :mod:`mslab.fast.compose` copies it into a module generated for
one combination of effect kernels, appends ``scene_forces`` (the sum of the effects' ``kernel``
functions) and compiles each function with :func:`mslab.jit.compiled` (``error_model="numpy"``):
numba inlines the kernels into the loops and caches them. Nothing here knows any effect.

**Memory.** Arrays are C-contiguous and *coordinate-major*, ``x``, ``v`` of shape ``(dim,
n_particles)``; ``scene_forces`` hands the kernels the transposes (``(n_particles, dim)`` views,
numba's layout "F"), so a kernel indexes ``x[p, c]`` while a run of springs streams each
coordinate without shuffles (:mod:`mslab.effects.spring_kernels`; forces bitwise those of
particle-major memory). Saved samples are particle-major. Float64, or float32: state, forces,
buffers and particle updates in float32 (the step's scalars ``dt a_ij`` rounded to it); the
dissipated work and the samples float64.

**Passes.** Forces accumulate into a scratch ``f`` that holds the constant forces ``f0`` between
uses (:class:`mslab.fast.ForceModel`), restored by the pass that reads ``f``; a kick, the next
drift and the blow-up test are one pass, which forms ``a = f / m`` without storing it. Passes run
on flat views with the inverse mass tiled per coordinate (``w``), branch-free: numba vectorises
them (8x a two-index loop on a 300 x 300 cloth). On a big scene the splitting loop's pass
(:func:`_particle_pass`) runs on all threads over the parts ``cuts``
(:func:`mslab.fast.model.particle_cuts`); each entry gets the same operations on any thread.
Where the last kernel has a twin that kicks each block of particles as soon as its forces are
complete (:func:`mslab.effects.spring_kick.spring_kernel_kick`), the explicit kick's forces and
pass are one call, ``scene_forces_kick``, with one parallel launch fewer a step.

Every loop returns ``(step, k, dissipated, status, n_force)``: the last step taken, the next free
save slot, :data:`OK` or :data:`BLOWUP` (``step`` blew up), and the number of force evaluations;
states whose step is in ``saved[k:]`` go to ``xs, vs, ds``.
"""

from __future__ import annotations

import numpy as np

from mslab.jit import prange
from mslab.kicks import kick as _kick

OK = 0
BLOWUP = 1
VERLET = 2
LEAPFROG = 3

#: the particle passes of the splitting loop (:func:`_particle_pass`)
KICK, KICK_KEEP, KICK_WITH, DRIFT = 0, 1, 2, 3


def rhs(x, v, a, w, f0, params):
    """Acceleration ``a = M^-1 (f0 + sum_e f_e(x, v))`` into ``a``; returns the dissipated power."""
    af = a.reshape(a.size)
    f0f = f0.reshape(f0.size)
    for e in range(af.size):
        af[e] = f0f[e]
    power = scene_forces(x, v, a, params)
    for e in range(af.size):
        af[e] = w[e] * af[e]
    return power


def _save(x, v, dissipated, xs, vs, ds, k):
    """Save the state (coordinate-major) as the sample ``k`` (particle-major, ``(n_particles, dim)``)."""
    xs[k] = x.T
    vs[k] = v.T
    ds[k] = dissipated


def _drift(xf, vf, hd):
    for e in range(xf.size):
        xf[e] = xf[e] + hd * vf[e]


def _kick_keep(xf, vf, ff, f0f, w, h, hd, mem_a, limit):
    """:func:`mslab.kicks.kick` that also keeps ``a`` in ``mem_a`` (first same as last)."""
    count = 0
    for e in range(xf.size):
        aq = w[e] * ff[e]
        ff[e] = f0f[e]
        mem_a[e] = aq
        vq = vf[e] + h * aq
        vf[e] = vq
        xq = xf[e] + hd * vq
        xf[e] = xq
        count += 0 if (abs(xq) < limit and vq - vq == 0.0) else 1
    return count


def _kick_with(xf, vf, af, h, hd, limit):
    """``v += h a; x += hd v`` with a known acceleration; returns the count of bad entries."""
    count = 0
    for e in range(xf.size):
        vq = vf[e] + h * af[e]
        vf[e] = vq
        xq = xf[e] + hd * vq
        xf[e] = xq
        count += 0 if (abs(xq) < limit and vq - vq == 0.0) else 1
    return count


def _particle_pass(code, xf, vf, ff, f0f, w, maf, h, hd, limit, cuts):
    """Do one pass over the particles, in parts on all threads; return the count of bad entries.

    ``code`` picks :func:`mslab.kicks.kick`, :func:`_kick_keep`, :func:`_kick_with` or :func:`_drift`.
    A drift counts none. With more than one part in ``cuts`` (entries ``cuts[p]:cuts[p+1]``)
    the parts run on all threads (numba's ``prange``); a pass is elementwise, so each entry
    gets the same operations on any number of threads.
    Cost ``O(n dim)``, span ``O(n dim / threads)`` and one launch (tens of microseconds with
    sleeping threads: :func:`mslab.fast.model.particle_cuts` keeps small scenes on one).
    """
    parts = cuts.shape[0] - 1
    if parts == 1:
        return _part(code, xf, vf, ff, f0f, w, maf, h, hd, limit)
    bad = np.empty(parts, np.int64)
    for p in prange(parts):
        lo = cuts[p]
        hi = cuts[p + 1]
        bad[p] = _part(code, xf[lo:hi], vf[lo:hi], ff[lo:hi], f0f[lo:hi], w[lo:hi], maf[lo:hi],
                       h, hd, limit)
    count = 0
    for p in range(parts):
        count += bad[p]
    return count


def _part(code, xf, vf, ff, f0f, w, maf, h, hd, limit):
    """Do the pass ``code`` of :func:`_particle_pass` over these entries (each pass its own loop)."""
    if code == KICK:
        return _kick(xf, vf, ff, f0f, w, h, hd, limit)
    if code == KICK_KEEP:
        return _kick_keep(xf, vf, ff, f0f, w, h, hd, maf, limit)
    if code == KICK_WITH:
        return _kick_with(xf, vf, maf, h, hd, limit)
    _drift(xf, vf, hd)
    return 0


def run_explicit_rk(x, v, dissipated, A, b, dt, step, n_steps, saved, k, xs, vs, ds, limit,
                    cuts, w, f0, params):
    """Take steps of an explicit Runge-Kutta tableau (notes, eqs. 16-20), ``y = (x, v)``, ``F = (v, a)``.

    ``Y_s = y_n + h sum_{r<s} A_sr K_r``, ``y_{n+1} = y_n + h sum_s b_s K_s``; the dissipated
    work gets the weights ``b`` too. ``kx[s]`` is the stage velocity, ``kv[s]`` its acceleration.
    """
    dim, n = x.shape
    size = n * dim
    s = b.shape[0]
    xf = x.reshape(size)
    vf = v.reshape(size)
    f0f = f0.reshape(size)
    kx = np.empty((s, dim, n), x.dtype)
    kv = np.empty((s, dim, n), x.dtype)
    xi = np.empty((dim, n), x.dtype)
    xif = xi.reshape(size)
    kxf = kx.reshape((s, size))
    kvf = kv.reshape((s, size))
    power = np.empty(s)
    hA = (dt * A).astype(x.dtype)  # dt A and dt b in the state's precision (the particle updates')
    hb = (dt * b).astype(x.dtype)
    n_force = 0
    while step < n_steps:
        step += 1
        for st in range(s):
            for e in range(size):  # the stage (xi, kx[st]) and its force slot kv[st] = f0, one pass
                sx = xf[e]
                sv = vf[e]
                for r in range(st):
                    h = hA[st, r]
                    if h != 0.0:
                        sx = sx + h * kxf[r, e]
                        sv = sv + h * kvf[r, e]
                xif[e] = sx
                kxf[st, e] = sv
                kvf[st, e] = f0f[e]
            power[st] = scene_forces(xi, kx[st], kv[st], params)
            n_force += 1
            for e in range(size):
                kvf[st, e] = w[e] * kvf[st, e]
        work = 0.0
        for st in range(s):
            if b[st] != 0.0:
                work += dt * b[st] * power[st]
        bad = 0
        for e in range(size):  # y_{n+1} and the blow-up test, one pass
            sx = xf[e]
            sv = vf[e]
            for st in range(s):
                h = hb[st]
                if h != 0.0:
                    sx = sx + h * kxf[st, e]
                    sv = sv + h * kvf[st, e]
            xf[e] = sx
            vf[e] = sv
            bad += 0 if (abs(sx) < limit and sv - sv == 0.0) else 1
        dissipated = dissipated + work
        if k < saved.shape[0] and saved[k] == step:
            _save(x, v, dissipated, xs, vs, ds, k)
            k += 1
        if bad:
            return step, k, dissipated, BLOWUP, n_force
    return step, k, dissipated, OK, n_force


def _kick_rk(x, xf, vf, vi, f, f0f, w, acc, pws, kA, kb, h, hd, limit, params):
    """Kick by one step of the explicit tableau ``(kA, kb)`` on ``v' = a(x, v)``, x fixed; then drift.

    Stage ``r``: ``V_r = v + h sum_{u<r} kA[r, u] a_u``, ``a_r = a(x, V_r)`` (into ``acc[r]``);
    then ``v += h sum_r kb[r] a_r``, ``x += hd v`` and the blow-up test in one pass. Returns
    the kick's power ``sum_r kb[r] P_r`` and the count of bad entries.
    """
    ns = kb.shape[0]
    size = xf.size
    vif = vi.reshape(vi.size)
    ff = f.reshape(size)
    for r in range(ns):
        for e in range(size):
            sv = vf[e]
            for u in range(r):
                hu = xf.dtype.type(h * kA[r, u])
                if hu != 0.0:
                    sv = sv + hu * acc[u, e]
            vif[e] = sv
        pws[r] = scene_forces(x, vi, f, params)
        for e in range(size):
            acc[r, e] = w[e] * ff[e]
            ff[e] = f0f[e]
    pw = 0.0
    for r in range(ns):
        if kb[r] != 0.0:
            pw += kb[r] * pws[r]
    bad = 0
    for e in range(size):
        vq = vf[e]
        for r in range(ns):
            hb = xf.dtype.type(h * kb[r])
            if hb != 0.0:
                vq = vq + hb * acc[r, e]
        vf[e] = vq
        xq = xf[e] + hd * vq
        xf[e] = xq
        bad += 0 if (abs(xq) < limit and vq - vq == 0.0) else 1
    return pw, bad


def run_splitting(x, v, dissipated, drift, kick, reuse, kA, kb, mem_a, mem_p,
                  dt, step, n_steps, saved, k, xs, vs, ds, limit, cuts, w, f0, params, threads):
    """Take steps of a drift/kick splitting (``mslab/integrators/families/splitting.py``).

    ``x += a_0 h v; v += b_0 h a; x += a_1 h v; ...; x += a_k h v`` with ``a = drift``,
    ``b = kick``. ``reuse``: the first kick takes the acceleration of the previous step's
    last kick from ``mem_a, mem_p`` (first same as last; ``mem_a`` is updated in place).
    A kick is one step of the explicit tableau ``(kA, kb)`` on ``v' = a(x, v)`` with x
    fixed: with one stage (forces independent of v, or order 1) the plain kick ``v += b h a``.
    A kick, the drift after it and the blow-up test are one pass (the test counts at the
    last kick only). The passes without stages run on all threads over the parts ``cuts``
    (:func:`_particle_pass`); ``threads``, the threads of the parallel loops now: on more
    than one, the last kernel's kick twin may do the explicit kick's pass (``scene_forces_kick``).
    """
    dim, n = x.shape
    size = n * dim
    nk = kick.shape[0]
    ns = kb.shape[0]
    xf = x.reshape(size)
    vf = v.reshape(size)
    f = f0.copy()
    ff = f.reshape(size)
    f0f = f0.reshape(size)
    maf = mem_a.reshape(size)
    acc = np.empty((ns if ns > 1 else 0, size), x.dtype)
    pws = np.empty(ns)
    vi = np.empty((dim, n) if ns > 1 else (dim, 0), x.dtype)
    n_force = 0
    zero = x.dtype.type(0.0)
    p_last = mem_p[0]
    while step < n_steps:
        step += 1
        work = 0.0
        bad = 0
        if drift[0] != 0.0:
            _particle_pass(DRIFT, xf, vf, ff, f0f, w, maf, zero, x.dtype.type(dt * drift[0]), limit, cuts)
        for st in range(nk):
            h = dt * kick[st]  # (float64: the dissipated work's weight)
            hs = x.dtype.type(h)  # the updates' steps in the state's precision
            hd = x.dtype.type(dt * drift[st + 1])
            last = st == nk - 1
            if st == 0 and reuse:  # a from the previous step's last kick
                pw = p_last
                bad = _particle_pass(KICK_WITH, xf, vf, ff, f0f, w, maf, hs, hd, limit, cuts)
            elif ns > 1:  # velocity-dependent forces: one step of (kA, kb) in v, x fixed
                pw, bad = _kick_rk(x, xf, vf, vi, f, f0f, w, acc, pws, kA, kb, h, hd, limit, params)
                n_force += ns
            elif reuse and last:
                pw = scene_forces(x, v, f, params)
                n_force += 1
                bad = _particle_pass(KICK_KEEP, xf, vf, ff, f0f, w, maf, hs, hd, limit, cuts)
            else:  # the explicit kick: forces, then kick + drift + test in one pass
                pw, bad = scene_forces_kick(x, v, f, params, xf, vf, ff, f0f, w, maf, hs, hd, limit, cuts,
                                            threads)
                n_force += 1
            work += h * pw
            p_last = pw
        dissipated = dissipated + work
        if k < saved.shape[0] and saved[k] == step:
            _save(x, v, dissipated, xs, vs, ds, k)
            k += 1
        if bad:
            mem_p[0] = p_last
            return step, k, dissipated, BLOWUP, n_force
    mem_p[0] = p_last
    return step, k, dissipated, OK, n_force


def run_two_step(method, x, v, dissipated, mem_x, mem_a, mem_p, dt, step, n_steps, saved, k,
                 xs, vs, ds, limit, velocity_dependent, cuts, w, f0, params):
    """Take steps of Verlet and leapfrog (``integrators/families/two_step.py``, eqs. 21-26 of the notes).

    One force evaluation ``a = a(X, V)`` per step:

    * VERLET: ``(X, V) = (x_n, v_n)``; ``x_{n+1} = 2 x_n - x_{n-1} + h^2 a``,
      ``v_{n+1} = (x_{n+1} - x_n)/h + h/2 a`` (memory ``mem_x = x_{n-1}``, ``mem_p = [P_{n-1}]``);
    * LEAPFROG: ``X = x_n + h v_{n+1/2}``, ``V = v_{n+1/2} (+ h/2 a_n if forces depend on v)``;
      ``v_{n+1} = v_{n+1/2} + h/2 a``, ``v_{n+3/2} = v_{n+1/2} + h a`` (``mem_x = v_{n+1/2}``,
      ``mem_a = a_n``, ``mem_p = [P_n]``).

    Memory arrays are updated in place.
    """
    dim, n = x.shape
    size = n * dim
    xf = x.reshape(size)
    vf = v.reshape(size)
    mxf = mem_x.reshape(size)
    maf = mem_a.reshape(size)
    f = f0.copy()
    ff = f.reshape(size)
    f0f = f0.reshape(size)
    verlet = method == VERLET
    xg = x if verlet else np.empty((dim, n), x.dtype)
    vg = v if verlet else np.empty((dim, n), x.dtype)
    xgf = xg.reshape(size)
    vgf = vg.reshape(size)
    ty = x.dtype.type  # the updates' constants in the state's precision
    two, hs, dt2, half = ty(2.0), ty(dt), ty(dt * dt), ty(0.5 * dt)
    n_force = 0
    while step < n_steps:
        step += 1
        if not verlet:
            for e in range(size):
                xgf[e] = xf[e] + hs * mxf[e]
                vgf[e] = mxf[e] + half * maf[e] if velocity_dependent else mxf[e]
        pw = scene_forces(xg, vg, f, params)
        n_force += 1
        bad = 0
        if verlet:
            for e in range(size):
                aq = w[e] * ff[e]
                ff[e] = f0f[e]
                xo = xf[e]
                x_new = two * xo - mxf[e] + dt2 * aq
                vq = (x_new - xo) / hs + half * aq
                vf[e] = vq
                mxf[e] = xo
                xf[e] = x_new
                bad += 0 if (abs(x_new) < limit and vq - vq == 0.0) else 1
            dissipated = dissipated + 0.5 * dt * (3.0 * pw - mem_p[0])
        else:
            for e in range(size):
                aq = w[e] * ff[e]
                ff[e] = f0f[e]
                xq = xgf[e]
                xf[e] = xq
                vq = mxf[e] + half * aq
                vf[e] = vq
                mxf[e] = mxf[e] + hs * aq
                maf[e] = aq
                bad += 0 if (abs(xq) < limit and vq - vq == 0.0) else 1
            dissipated = dissipated + 0.5 * dt * (mem_p[0] + pw)
        mem_p[0] = pw
        if k < saved.shape[0] and saved[k] == step:
            _save(x, v, dissipated, xs, vs, ds, k)
            k += 1
        if bad:
            return step, k, dissipated, BLOWUP, n_force
    return step, k, dissipated, OK, n_force


# -- scene forces (generated) --
# mslab.fast.compose cuts the template here and appends the scene's ``scene_forces`` and
# ``scene_forces_kick`` (the forces, then the pass KICK; returns the power and the bad count).
def scene_forces(x, v, f, params):
    """Stand in for the scene's forces in the template (never compiled)."""
    raise NotImplementedError("mslab.fast.loops is a template; use mslab.fast.compose")


def scene_forces_kick(x, v, f, params, xf, vf, ff, f0f, w, maf, h, hd, limit, cuts, threads):
    """Stand in for the scene's forces and kick pass in the template (never compiled)."""
    raise NotImplementedError("mslab.fast.loops is a template; use mslab.fast.compose")
