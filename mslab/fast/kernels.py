"""Compiled kernels (numba): the same equations as the numpy effects and integrators, as loops.

Every kernel mirrors a readable numpy reference in ``mslab/effects`` or ``mslab/integrators``
and is tested equal to it (``tests/test_fast.py``). Arrays are float64, C-contiguous:
positions ``x`` and velocities ``v`` of shape ``(n_particles, dim)``; spring pairs as two
int64 arrays ``i, j`` of shape ``(n_springs,)``.

The force model of the compiled path is the sum of three effects (any of them may be
absent: zero stiffness arrays, zero gravity force, ``gamma = 0``):

* Hooke springs with damping along the spring (seed eqs. 1-2)::

      d = x_i - x_j,  l = |d|,  u = d / l,
      f_i = -k (d - L u) - c (u . (v_i - v_j)) u,      f_j = -f_i,      P = c (u . Δv)^2

* gravity ``f_i = m_i g`` (precomputed as an array ``f_gravity``),
* viscous drag ``f_i = -gamma v_i``, ``P = gamma |v_i|^2``,

and the acceleration is ``a_i = f_i / m_i`` (``inv_mass = 0`` for pinned particles).

Compiled code is cached on disk (``cache=True``): the first use in a fresh checkout
compiles for a few seconds, later processes load it in a fraction of a second.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Status codes returned by the stepping loops.
OK = 0
BLOWUP = 1


@njit(cache=True)
def spring_forces(x, v, i, j, stiffness, rest_length, damping, damped, f):
    """Add the spring forces to ``f`` (n_particles, dim) in place; return the dissipated power.

    A loop over springs: the pair force ``f_q`` goes to ``+f[i]`` and ``-f[j]``.
    A spring of zero length has ``u = 0`` and exerts ``-k d = 0`` (never NaN).
    """
    dim = x.shape[1]
    if dim == 3:  # the common case, written out with scalars so the compiler keeps them in registers
        return _spring_forces_3d(x, v, i, j, stiffness, rest_length, damping, damped, f)
    power = 0.0
    d = np.empty(dim)
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        length2 = 0.0
        for c in range(dim):
            d[c] = x[a, c] - x[b, c]
            length2 += d[c] * d[c]
        length = np.sqrt(length2)
        inv_l = 1.0 / length if length > 0.0 else 0.0
        k = stiffness[q]
        lu = rest_length[q] * inv_l  # L u = (L / l) d
        if damped:
            rate = 0.0  # u . (v_i - v_j), the stretch rate
            for c in range(dim):
                rate += d[c] * inv_l * (v[a, c] - v[b, c])
            cr = damping[q] * rate
            power += cr * rate
            for c in range(dim):
                fc = -k * (d[c] - lu * d[c]) - cr * (d[c] * inv_l)
                f[a, c] += fc
                f[b, c] -= fc
        else:
            for c in range(dim):
                fc = -k * (d[c] - lu * d[c])
                f[a, c] += fc
                f[b, c] -= fc
    return power


@njit(cache=True)
def _spring_forces_3d(x, v, i, j, stiffness, rest_length, damping, damped, f):
    """:func:`spring_forces` for dim = 3: the same equations with ``d = (dx, dy, dz)``."""
    power = 0.0
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1]
        dz = x[a, 2] - x[b, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        inv_l = 1.0 / length if length > 0.0 else 0.0
        k = stiffness[q]
        lu = rest_length[q] * inv_l
        fx = -k * (dx - lu * dx)
        fy = -k * (dy - lu * dy)
        fz = -k * (dz - lu * dz)
        if damped:
            rate = (dx * inv_l * (v[a, 0] - v[b, 0]) + dy * inv_l * (v[a, 1] - v[b, 1])
                    + dz * inv_l * (v[a, 2] - v[b, 2]))
            cr = damping[q] * rate
            power += cr * rate
            fx -= cr * (dx * inv_l)
            fy -= cr * (dy * inv_l)
            fz -= cr * (dz * inv_l)
        f[a, 0] += fx
        f[a, 1] += fy
        f[a, 2] += fz
        f[b, 0] -= fx
        f[b, 1] -= fy
        f[b, 2] -= fz
    return power


@njit(cache=True)
def spring_force(x, v, i, j, stiffness, rest_length, damping, damped):
    """Spring forces alone: ``(f, power)`` with ``f`` of shape (n_particles, dim)."""
    f = np.zeros_like(x)
    power = spring_forces(x, v, i, j, stiffness, rest_length, damping, damped, f)
    return f, power


@njit(cache=True)
def rhs(x, v, inv_mass, i, j, stiffness, rest_length, damping, damped, f_gravity, gamma, a):
    """Acceleration into ``a`` (n_particles, dim) and the dissipated power (returned).

    ``a = M^-1 (f_springs + f_gravity - gamma v)``, as ``System.rhs``.
    """
    n, dim = x.shape
    for p in range(n):
        for c in range(dim):
            a[p, c] = 0.0
    power = spring_forces(x, v, i, j, stiffness, rest_length, damping, damped, a)
    for p in range(n):
        for c in range(dim):
            a[p, c] = inv_mass[p] * (a[p, c] + f_gravity[p, c] - gamma * v[p, c])
    if gamma != 0.0:
        for p in range(n):
            for c in range(dim):
                power += gamma * v[p, c] * v[p, c]
    return power


@njit(cache=True)
def _blown_up(x, v, limit):
    """A non-finite entry or a position beyond ``limit``: the blow-up test of ``simulate``."""
    n, dim = x.shape
    for p in range(n):
        for c in range(dim):
            if not (np.isfinite(x[p, c]) and np.isfinite(v[p, c]) and abs(x[p, c]) < limit):
                return True
    return False


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
                    inv_mass, i, j, stiffness, rest_length, damping, damped, f_gravity, gamma):
    """Steps ``step+1 .. n_steps`` of an explicit Runge-Kutta tableau (seed eqs. 16-20).

    ``Y_s = y_n + h sum_{r<s} A_sr K_r``, ``K_s = F(Y_s)``, ``y_{n+1} = y_n + h sum_s b_s K_s``
    with ``y = (x, v)``, ``F(y) = (v, a(x, v))``; the dissipated work gets the same weights b.
    ``x, v`` are advanced in place; the states with indices in ``saved[k:]`` go to
    ``xs, vs, ds``. Returns ``(step, k, dissipated, status, n_force)``: the last step taken, the next
    free save slot, OK or BLOWUP (then ``step`` is the step that blew up), and the number of
    force evaluations made.
    """
    n, dim = x.shape
    s = b.shape[0]
    kx = np.empty((s, n, dim))
    kv = np.empty((s, n, dim))
    power = np.empty(s)
    n_force = 0
    xi = np.empty((n, dim))
    vi = np.empty((n, dim))
    while step < n_steps:
        step += 1
        for st in range(s):
            for p in range(n):
                for c in range(dim):
                    xi[p, c] = x[p, c]
                    vi[p, c] = v[p, c]
            for r in range(st):
                if A[st, r] != 0.0:
                    h = dt * A[st, r]
                    for p in range(n):
                        for c in range(dim):
                            xi[p, c] = xi[p, c] + h * kx[r, p, c]
                            vi[p, c] = vi[p, c] + h * kv[r, p, c]
            power[st] = rhs(xi, vi, inv_mass, i, j, stiffness, rest_length, damping, damped,
                            f_gravity, gamma, kv[st])
            n_force += 1
            for p in range(n):
                for c in range(dim):
                    kx[st, p, c] = vi[p, c]
        work = 0.0
        for st in range(s):
            if b[st] != 0.0:
                h = dt * b[st]
                for p in range(n):
                    for c in range(dim):
                        x[p, c] = x[p, c] + h * kx[st, p, c]
                        v[p, c] = v[p, c] + h * kv[st, p, c]
                work += h * power[st]
        dissipated = dissipated + work
        if k < saved.shape[0] and saved[k] == step:
            _save(x, v, dissipated, xs, vs, ds, k)
            k += 1
        if _blown_up(x, v, limit):
            return step, k, dissipated, BLOWUP, n_force
    return step, k, dissipated, OK, n_force


# The two-step forms of the course, by number.
VERLET = 2
LEAPFROG = 3


@njit(cache=True)
def run_splitting(x, v, dissipated, drift, kick, reuse, kA, kb, mem_a, mem_p,
                  dt, step, n_steps, saved, k, xs, vs, ds, limit,
                  inv_mass, i, j, stiffness, rest_length, damping, damped, f_gravity, gamma):
    """Steps of a drift/kick splitting (``mslab/integrators/splitting.py``).

    ``x += a_0 h v; v += b_0 h a; x += a_1 h v; ...; x += a_k h v`` with ``a = drift``,
    ``b = kick``. ``reuse``: the first kick takes the acceleration of the previous step's
    last kick from ``mem_a, mem_p`` (first same as last). Each kick is one step of the
    explicit tableau ``(kA, kb)`` on ``v' = a(x, v)`` with x fixed (a one-stage Euler
    tableau when forces do not depend on velocity). Returns
    ``(step, k, dissipated, status, n_force)``.
    """
    n, dim = x.shape
    nk = kick.shape[0]
    ns = kb.shape[0]
    acc = np.empty((ns, n, dim))
    pw = np.empty(ns)
    vi = np.empty((n, dim))
    n_force = 0
    p = 0.0
    while step < n_steps:
        step += 1
        work = 0.0
        for st in range(nk):
            if drift[st] != 0.0:
                hd = dt * drift[st]
                for q in range(n):
                    for c in range(dim):
                        x[q, c] = x[q, c] + hd * v[q, c]
            h = dt * kick[st]
            for r in range(ns):
                if r == 0 and st == 0 and reuse:
                    for q in range(n):
                        for c in range(dim):
                            acc[0, q, c] = mem_a[q, c]
                    pw[0] = mem_p[0]
                    continue
                for q in range(n):
                    for c in range(dim):
                        vi[q, c] = v[q, c]
                for u in range(r):
                    if kA[r, u] != 0.0:
                        hu = h * kA[r, u]
                        for q in range(n):
                            for c in range(dim):
                                vi[q, c] = vi[q, c] + hu * acc[u, q, c]
                pw[r] = rhs(x, vi, inv_mass, i, j, stiffness, rest_length, damping, damped, f_gravity,
                            gamma, acc[r])
                n_force += 1
            p = 0.0
            for r in range(ns):
                if kb[r] != 0.0:
                    hb = h * kb[r]
                    for q in range(n):
                        for c in range(dim):
                            v[q, c] = v[q, c] + hb * acc[r, q, c]
                    p += kb[r] * pw[r]
            work += h * p
        if drift[nk] != 0.0:
            hd = dt * drift[nk]
            for q in range(n):
                for c in range(dim):
                    x[q, c] = x[q, c] + hd * v[q, c]
        if reuse:
            for q in range(n):
                for c in range(dim):
                    mem_a[q, c] = acc[0, q, c]
            mem_p[0] = pw[0]
        dissipated = dissipated + work
        if k < saved.shape[0] and saved[k] == step:
            _save(x, v, dissipated, xs, vs, ds, k)
            k += 1
        if _blown_up(x, v, limit):
            return step, k, dissipated, BLOWUP, n_force
    return step, k, dissipated, OK, n_force


@njit(cache=True)
def run_two_step(method, x, v, dissipated, mem_x, mem_a, mem_p, dt, step, n_steps, saved, k,
                 xs, vs, ds, limit, velocity_dependent,
                 inv_mass, i, j, stiffness, rest_length, damping, damped, f_gravity, gamma):
    """Steps of Verlet and leapfrog (``mslab/integrators/two_step.py``, seed eqs. 21-26).

    One force evaluation ``a = a(X, V)`` per step:

    * VERLET: ``(X, V) = (x_n, v_n)``; ``x_{n+1} = 2 x_n - x_{n-1} + h^2 a``,
      ``v_{n+1} = (x_{n+1} - x_n)/h + h/2 a`` (memory ``mem_x = x_{n-1}``, ``mem_p = [P_{n-1}]``);
    * LEAPFROG: ``X = x_n + h v_{n+1/2}``, ``V = v_{n+1/2} (+ h/2 a_n if forces depend on v)``;
      ``v_{n+1} = v_{n+1/2} + h/2 a``, ``v_{n+3/2} = v_{n+1/2} + h a`` (``mem_x = v_{n+1/2}``,
      ``mem_a = a_n``, ``mem_p = [P_n]``).

    Memory arrays are updated in place. Returns ``(step, k, dissipated, status, n_force)``.
    """
    n, dim = x.shape
    a = np.empty((n, dim))
    xg = np.empty((n, dim))
    vg = np.empty((n, dim))
    n_force = 0
    while step < n_steps:
        step += 1
        for q in range(n):
            for c in range(dim):
                if method == VERLET:
                    xg[q, c] = x[q, c]
                    vg[q, c] = v[q, c]
                else:
                    xg[q, c] = x[q, c] + dt * mem_x[q, c]
                    if velocity_dependent:
                        vg[q, c] = mem_x[q, c] + (0.5 * dt) * mem_a[q, c]
                    else:
                        vg[q, c] = mem_x[q, c]
        p = rhs(xg, vg, inv_mass, i, j, stiffness, rest_length, damping, damped, f_gravity, gamma, a)
        n_force += 1
        for q in range(n):
            for c in range(dim):
                if method == VERLET:
                    x_new = 2.0 * x[q, c] - mem_x[q, c] + (dt * dt) * a[q, c]
                    v[q, c] = (x_new - x[q, c]) / dt + (0.5 * dt) * a[q, c]
                    mem_x[q, c] = x[q, c]
                    x[q, c] = x_new
                else:
                    x[q, c] = xg[q, c]
                    v[q, c] = mem_x[q, c] + (0.5 * dt) * a[q, c]
                    mem_x[q, c] = mem_x[q, c] + dt * a[q, c]
                    mem_a[q, c] = a[q, c]
        if method == VERLET:
            dissipated = dissipated + 0.5 * dt * (3.0 * p - mem_p[0])
        else:
            dissipated = dissipated + 0.5 * dt * (mem_p[0] + p)
        mem_p[0] = p
        if k < saved.shape[0] and saved[k] == step:
            _save(x, v, dissipated, xs, vs, ds, k)
            k += 1
        if _blown_up(x, v, limit):
            return step, k, dissipated, BLOWUP, n_force
    return step, k, dissipated, OK, n_force


@njit(cache=True)
def energies(xs, vs, mass, free, i, j, stiffness, rest_length, f_gravity):
    """Kinetic and potential energy of each saved state: two arrays of shape (n_saved,).

    ``K = sum_free m |v|^2 / 2``, ``U = sum_q k (l_q - L_q)^2 / 2 - sum_p f_gravity_p . x_p``.
    """
    n_saved, n, dim = xs.shape
    kinetic = np.zeros(n_saved)
    potential = np.zeros(n_saved)
    for s in range(n_saved):
        kin = 0.0
        pot_g = 0.0
        for p in range(n):
            for c in range(dim):
                if free[p]:
                    kin += mass[p] * vs[s, p, c] * vs[s, p, c]
                pot_g -= f_gravity[p, c] * xs[s, p, c]
        pot_s = 0.0
        for q in range(i.shape[0]):
            length2 = 0.0
            for c in range(dim):
                dc = xs[s, i[q], c] - xs[s, j[q], c]
                length2 += dc * dc
            stretch = np.sqrt(length2) - rest_length[q]
            pot_s += stiffness[q] * stretch * stretch
        kinetic[s] = 0.5 * kin
        potential[s] = 0.5 * pot_s + pot_g
    return kinetic, potential
