"""The compiled stepping loops: one per method family, generic over the scene's effects.

This file is a *template*: :mod:`mslab.fast.compose` copies its text into a module generated
for one combination of effect kernels and appends the definition of ``scene_forces`` (the
sum of the effects' own ``kernel`` functions), so numba compiles, inlines and caches the
loops for that combination (``cache=True``: a later process loads them in a fraction of a
second). Nothing here knows any effect. Arrays are float64, C-contiguous: positions ``x``
and velocities ``v`` of shape ``(n_particles, dim)``.

The loops are lean (issue 14): forces accumulate into a scratch array ``f`` that is kept
zero between uses (each consuming pass zeroes what it read, so no separate zeroing pass);
a kick, the following drift and the blow-up test of the step share one pass over the
particles; the acceleration ``a = f / m`` is formed in that pass, not stored.

Every loop returns ``(step, k, dissipated, status, n_force)``: the last step taken, the next
free save slot, :data:`OK` or :data:`BLOWUP` (then ``step`` is the step that blew up), and
the number of force evaluations made; states whose step is in ``saved[k:]`` go to
``xs, vs, ds``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

OK = 0
BLOWUP = 1
VERLET = 2
LEAPFROG = 3


@njit(cache=True)
def rhs(x, v, a, inv_mass, params):
    """Acceleration ``a = M^-1 sum_e f_e(x, v)`` into ``a``; returns the dissipated power."""
    n, dim = x.shape
    for p in range(n):
        for c in range(dim):
            a[p, c] = 0.0
    power = scene_forces(x, v, a, params)
    for p in range(n):
        m = inv_mass[p]
        for c in range(dim):
            a[p, c] = m * a[p, c]
    return power


@njit(cache=True)
def _save(x, v, dissipated, xs, vs, ds, k):
    n, dim = x.shape
    for p in range(n):
        for c in range(dim):
            xs[k, p, c] = x[p, c]
            vs[k, p, c] = v[p, c]
    ds[k] = dissipated


@njit(cache=True)
def run_explicit_rk(x, v, dissipated, A, b, dt, step, n_steps, saved, k, xs, vs, ds, limit,
                    inv_mass, params):
    """Steps of an explicit Runge-Kutta tableau (seed eqs. 16-20), ``y = (x, v)``, ``F = (v, a)``.

    ``Y_s = y_n + h sum_{r<s} A_sr K_r``, ``y_{n+1} = y_n + h sum_s b_s K_s``; the dissipated
    work gets the weights ``b`` too.
    """
    n, dim = x.shape
    s = b.shape[0]
    kx = np.empty((s, n, dim))
    kv = np.zeros((s, n, dim))
    xi = np.empty((n, dim))
    power = np.empty(s)
    n_force = 0
    while step < n_steps:
        step += 1
        for st in range(s):
            for p in range(n):  # the stage (xi, kx[st]) and a zeroed force slot kv[st], one pass
                for c in range(dim):
                    sx = x[p, c]
                    sv = v[p, c]
                    for r in range(st):
                        if A[st, r] != 0.0:
                            h = dt * A[st, r]
                            sx = sx + h * kx[r, p, c]
                            sv = sv + h * kv[r, p, c]
                    xi[p, c] = sx
                    kx[st, p, c] = sv
                    kv[st, p, c] = 0.0
            power[st] = _stage_rhs(xi, kx[st], kv[st], inv_mass, params)
            n_force += 1
        work = 0.0
        for st in range(s):
            if b[st] != 0.0:
                work += dt * b[st] * power[st]
        bad = False
        for p in range(n):  # y_{n+1} and the blow-up test, one pass
            for c in range(dim):
                sx = x[p, c]
                sv = v[p, c]
                for st in range(s):
                    if b[st] != 0.0:
                        h = dt * b[st]
                        sx = sx + h * kx[st, p, c]
                        sv = sv + h * kv[st, p, c]
                x[p, c] = sx
                v[p, c] = sv
                if not (abs(sx) < limit and np.isfinite(sv)):
                    bad = True
        dissipated = dissipated + work
        if k < saved.shape[0] and saved[k] == step:
            _save(x, v, dissipated, xs, vs, ds, k)
            k += 1
        if bad:
            return step, k, dissipated, BLOWUP, n_force
    return step, k, dissipated, OK, n_force


@njit(cache=True)
def _stage_rhs(xi, vi, a, inv_mass, params):
    """``a = M^-1 f(xi, vi)`` for a stage whose ``a`` is already zero; returns the power."""
    n, dim = xi.shape
    power = scene_forces(xi, vi, a, params)
    for p in range(n):
        m = inv_mass[p]
        for c in range(dim):
            a[p, c] = m * a[p, c]
    return power


@njit(cache=True)
def run_splitting(x, v, dissipated, drift, kick, reuse, symmetric, mem_a, mem_p, corrections,
                  dt, step, n_steps, saved, k, xs, vs, ds, limit, inv_mass, params):
    """Steps of a drift/kick splitting (``mslab/integrators/splitting.py``).

    ``x += a_0 h v; v += b_0 h a; x += a_1 h v; ...; x += a_k h v`` with ``a = drift``,
    ``b = kick``. ``reuse``: the first kick takes the acceleration of the previous step's
    last kick from ``mem_a, mem_p`` (first same as last; ``mem_a`` is updated in place).
    ``symmetric``: each kick is ``v' = v + b h a(x, (v + v')/2)`` by ``corrections``
    fixed-point corrections from the explicit kick. A kick, the drift after it and (last
    kick) the blow-up test are one pass; the force scratch ``f`` is zeroed in that pass.
    """
    n, dim = x.shape
    nk = kick.shape[0]
    f = np.zeros((n, dim))
    vn = np.empty((n, dim)) if symmetric else np.empty((0, dim))
    vm = np.empty((n, dim)) if symmetric else np.empty((0, dim))
    n_force = 0
    p_last = mem_p[0]
    while step < n_steps:
        step += 1
        work = 0.0
        bad = False
        if drift[0] != 0.0:
            hd = dt * drift[0]
            for q in range(n):
                for c in range(dim):
                    x[q, c] = x[q, c] + hd * v[q, c]
        for st in range(nk):
            h = dt * kick[st]
            hd = dt * drift[st + 1]
            last = st == nk - 1
            keep = reuse and last
            if st == 0 and reuse:  # a from the previous step's last kick
                pw = p_last
                for q in range(n):
                    for c in range(dim):
                        vq = v[q, c] + h * mem_a[q, c]
                        v[q, c] = vq
                        if hd != 0.0:
                            x[q, c] = x[q, c] + hd * vq
                        if last and not (abs(x[q, c]) < limit and np.isfinite(vq)):
                            bad = True
            elif symmetric:  # v' = v + h a(x, (v + v') / 2): explicit kick, then corrections
                pw = scene_forces(x, v, f, params)
                n_force += 1
                for q in range(n):
                    m = inv_mass[q]
                    for c in range(dim):
                        vn[q, c] = v[q, c] + h * (m * f[q, c])
                        f[q, c] = 0.0
                for _ in range(corrections):
                    for q in range(n):
                        for c in range(dim):
                            vm[q, c] = 0.5 * (v[q, c] + vn[q, c])
                    pw = scene_forces(x, vm, f, params)
                    n_force += 1
                    for q in range(n):
                        m = inv_mass[q]
                        for c in range(dim):
                            vn[q, c] = v[q, c] + h * (m * f[q, c])
                            f[q, c] = 0.0
                for q in range(n):
                    for c in range(dim):
                        vq = vn[q, c]
                        v[q, c] = vq
                        if hd != 0.0:
                            x[q, c] = x[q, c] + hd * vq
                        if last and not (abs(x[q, c]) < limit and np.isfinite(vq)):
                            bad = True
            else:  # the explicit kick: forces, then kick + drift + test in one pass
                pw = scene_forces(x, v, f, params)
                n_force += 1
                for q in range(n):
                    m = inv_mass[q]
                    for c in range(dim):
                        aq = m * f[q, c]
                        f[q, c] = 0.0
                        if keep:
                            mem_a[q, c] = aq
                        vq = v[q, c] + h * aq
                        v[q, c] = vq
                        if hd != 0.0:
                            x[q, c] = x[q, c] + hd * vq
                        if last and not (abs(x[q, c]) < limit and np.isfinite(vq)):
                            bad = True
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


@njit(cache=True)
def run_two_step(method, x, v, dissipated, mem_x, mem_a, mem_p, dt, step, n_steps, saved, k,
                 xs, vs, ds, limit, velocity_dependent, inv_mass, params):
    """Steps of Verlet and leapfrog (``mslab/integrators/two_step.py``, seed eqs. 21-26).

    One force evaluation ``a = a(X, V)`` per step:

    * VERLET: ``(X, V) = (x_n, v_n)``; ``x_{n+1} = 2 x_n - x_{n-1} + h^2 a``,
      ``v_{n+1} = (x_{n+1} - x_n)/h + h/2 a`` (memory ``mem_x = x_{n-1}``, ``mem_p = [P_{n-1}]``);
    * LEAPFROG: ``X = x_n + h v_{n+1/2}``, ``V = v_{n+1/2} (+ h/2 a_n if forces depend on v)``;
      ``v_{n+1} = v_{n+1/2} + h/2 a``, ``v_{n+3/2} = v_{n+1/2} + h a`` (``mem_x = v_{n+1/2}``,
      ``mem_a = a_n``, ``mem_p = [P_n]``).

    Memory arrays are updated in place.
    """
    n, dim = x.shape
    f = np.zeros((n, dim))
    verlet = method == VERLET
    xg = x if verlet else np.empty((n, dim))
    vg = v if verlet else np.empty((n, dim))
    n_force = 0
    while step < n_steps:
        step += 1
        if not verlet:
            for q in range(n):
                for c in range(dim):
                    xg[q, c] = x[q, c] + dt * mem_x[q, c]
                    if velocity_dependent:
                        vg[q, c] = mem_x[q, c] + (0.5 * dt) * mem_a[q, c]
                    else:
                        vg[q, c] = mem_x[q, c]
        pw = scene_forces(xg, vg, f, params)
        n_force += 1
        bad = False
        for q in range(n):
            m = inv_mass[q]
            for c in range(dim):
                aq = m * f[q, c]
                f[q, c] = 0.0
                if verlet:
                    x_new = 2.0 * x[q, c] - mem_x[q, c] + (dt * dt) * aq
                    v[q, c] = (x_new - x[q, c]) / dt + (0.5 * dt) * aq
                    mem_x[q, c] = x[q, c]
                    x[q, c] = x_new
                else:
                    x[q, c] = xg[q, c]
                    v[q, c] = mem_x[q, c] + (0.5 * dt) * aq
                    mem_x[q, c] = mem_x[q, c] + dt * aq
                    mem_a[q, c] = aq
                if not (abs(x[q, c]) < limit and np.isfinite(v[q, c])):
                    bad = True
        if verlet:
            dissipated = dissipated + 0.5 * dt * (3.0 * pw - mem_p[0])
        else:
            dissipated = dissipated + 0.5 * dt * (mem_p[0] + pw)
        mem_p[0] = pw
        if k < saved.shape[0] and saved[k] == step:
            _save(x, v, dissipated, xs, vs, ds, k)
            k += 1
        if bad:
            return step, k, dissipated, BLOWUP, n_force
    return step, k, dissipated, OK, n_force


# -- scene forces (generated) --
# mslab.fast.compose cuts the template here and appends the scene's own ``scene_forces``:
# ``f += sum_e kernel_e(x, v, f, *params[e])``, returning the summed dissipated power.
def scene_forces(x, v, f, params):
    """Placeholder of the template (never compiled)."""
    raise NotImplementedError("mslab.fast.loops is a template; use mslab.fast.compose")
