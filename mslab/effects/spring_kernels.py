"""The compiled loops of the springs effect (:mod:`mslab.effects.springs`), in numba-compatible style.

The numpy methods of :class:`mslab.effects.springs.Springs` are the reference; the
functions here are the same equations as plain loops: :func:`spring_kernel` (forces and
dissipated power, composed into the stepping loops by :mod:`mslab.fast`; one statement of a
spring's force, :func:`pair_scale`, spring by spring or vectorised over runs) and
:func:`spring_jacobian_kernel` with :func:`scatter_pair_blocks` (the Jacobians of the
compiled Newton path, :mod:`mslab.fast.newton`). ``tests/test_fast.py`` and
``tests/test_newton_matrix.py`` hold them equal to the numpy code.
"""

from __future__ import annotations

import numpy as np

from mslab.jit import prange
from mslab.lanes import eight_lanes


def spring_kernel(x: np.ndarray, v: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray,
                  stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray,
                  damped: int, bounds: np.ndarray, run: np.ndarray, batches: np.ndarray,
                  phases: np.ndarray, gaps: np.ndarray) -> float:
    """Add the spring forces to ``f`` (n_particles, dim) in place; return the dissipated power.

    The springs come in conflict-free batches (:mod:`mslab.effects.spring_batches`): batch
    ``r`` is segments ``batches[r]:batches[r+1]`` (segment ``s``: springs
    ``bounds[s]:bounds[s+1]``, a vectorisable run if ``run[s]``), phase ``p`` is batches
    ``phases[p]:phases[p+1]``, and no two batches of one phase touch the same particle. The
    batches of a phase run on all threads (numba's ``prange``); each is summed by
    :func:`spring_batch` in its own order, and the powers of the batches are added in
    batch order, so the result is bitwise the same for any number of threads. A phase of one
    batch runs on the calling thread (no parallel launch: small scenes pay nothing). The
    springs ``gaps`` (ascending) are gap springs (:func:`mslab.effects.spring_batches.gap_springs`):
    they join rows into runs and exert no force.

    Cost: one square root and one division per spring; work ``O(n_springs)``, span
    ``O(n_springs / n_threads)`` plus the springs of the serial phases.
    """
    n_batches = batches.shape[0] - 1
    powers = np.empty(n_batches)  # (np.zeros would be a parallel loop of its own: a launch per call)
    for p in range(phases.shape[0] - 1):
        first = phases[p]
        last = phases[p + 1]
        if last - first > 1:
            for r in prange(first, last):
                powers[r] = spring_batch(x, v, f, i, j, stiffness, rest_length, damping, damped,
                                         bounds, run, gaps, batches[r], batches[r + 1])
        else:
            for r in range(first, last):
                powers[r] = spring_batch(x, v, f, i, j, stiffness, rest_length, damping, damped,
                                         bounds, run, gaps, batches[r], batches[r + 1])
    power = 0.0
    for r in range(n_batches):
        power += powers[r]
    return power


def spring_batch(x: np.ndarray, v: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray,
                 stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray, damped: int,
                 bounds: np.ndarray, run: np.ndarray, gaps: np.ndarray, first: int, last: int) -> float:
    """Add the forces of segments ``first:last`` (one batch) to ``f``; return their dissipated power.

    Plain segments (and every segment in one or two dimensions) go through
    :func:`spring_range`. A *run* in 3D (springs ``start:stop`` joining particles ``a + s`` and
    ``b + s``, ``b > a``: :func:`mslab.effects.spring_batches.segments`) is summed here in
    loops over contiguous memory that the compiler vectorises (square roots and divisions
    several at a time): :func:`run_pair` writes the pair forces ``f_q`` into ``pair`` (and the
    powers into ``rates``), then ``+f_q`` goes into the ``i`` ends and ``-f_q`` into the ``j``
    ends, a particle with both receiving ``-f`` of spring ``p - b`` before ``+f`` of spring
    ``p - a``: in spring order, so the forces are bitwise those of :func:`spring_range` over the
    batch. A run's powers are summed by :func:`lane_sum` (the same on every machine and thread
    count). A damped run with one stiffness and one damping (``run`` flags,
    :func:`mslab.effects.spring_batches.run_flags`) keeps them in registers. The pair loop runs
    to a multiple of 8 springs where the particles and table entries after the run exist (the
    extra pairs are dropped: no scalar remainder loop). Gap springs (``gaps``) are left out:
    see :func:`plain_segment` and :func:`zero_gaps`.

    A run is no call of its own (a compiled call with arrays costs numba's reference counting,
    ~120 ns) and makes no array view; particles are indexed by unsigned offsets (numba then adds
    no test for negative indices). The stepping loops hand ``x``, ``v``, ``f`` coordinate-major
    (``(3, n)`` memory seen as ``(n, 3)``, numba's layout "F": :mod:`mslab.fast.loops`), so a run
    reads and writes one contiguous row per coordinate, with no shuffles of interleaved x, y, z.
    """
    runs = x.shape[1] == 3
    longest = longest_run(bounds, run, first, last) if runs else 0  # the buffers' size
    pair = np.empty((3, longest + 7), x.dtype)  # a run's pair forces, a row per coordinate (+7, below)
    rates = np.empty(longest + 7 if damped else 0, x.dtype)  # a run's dissipated powers
    zero = stiffness.dtype.type(0.0)
    power = 0.0
    n_gaps = gaps.shape[0]
    g = first_at_least(gaps, bounds[first]) if first < last else n_gaps  # the next gap spring
    for s in range(first, last):
        if not (runs and run[s]):
            power, g = plain_segment(x, v, f, i, j, stiffness, rest_length, damping, damped, gaps, g,
                                     bounds[s], bounds[s + 1], power)
            continue
        q0 = np.uint64(bounds[s])  # spring q0 + t joins particles a + t and b + t
        m = np.int64(bounds[s + 1]) - np.int64(bounds[s])
        a, b = np.uint64(i[q0]), np.uint64(j[q0])
        # whole vectors: springs up to a multiple of 8 where the next particles and table entries
        # exist, their pairs computed into the buffers and never added (no scalar remainder loop)
        pad = (m + 7) // 8 * 8
        if np.int64(b) + pad > x.shape[0] or np.int64(q0) + pad > rest_length.shape[0]:
            pad = m
        if damped and (run[s] & 2) != 0:  # spring_batches.SAME_STIFFNESS: k and c in registers
            k0, c0 = stiffness[q0], damping[q0]
            for t in range(pad):
                q = np.uint64(t)
                run_pair(x, v, a, b, q, k0, rest_length[q0 + q], c0, 1, pair, rates)
        elif damped:
            for t in range(pad):
                q = np.uint64(t)
                run_pair(x, v, a, b, q, stiffness[q0 + q], rest_length[q0 + q], damping[q0 + q], 1,
                         pair, rates)
        else:  # (one stiffness in a register measured no faster here: the loads are not what bounds it)
            for t in range(pad):
                q = np.uint64(t)
                run_pair(x, x, a, b, q, stiffness[q0 + q], rest_length[q0 + q], zero, 0, pair, rates)
        if g < n_gaps and np.int64(gaps[g]) < np.int64(q0) + m:  # (no call for a run without gaps)
            g = zero_gaps(pair, rates, damped, gaps, g, q0, m)
        if damped:
            power += lane_sum(rates, m)
        for c in range(3):  # f[a + t] += pair[t] and f[b + t] -= pair[t], coordinate by coordinate
            scatter_row(f, pair, c, a, np.int64(b) - np.int64(a), m)
    return power


def first_at_least(values: np.ndarray, value: int) -> int:
    """Return the first index of the ascending ``values`` whose value is ``>= value`` (binary search).

    (``np.searchsorted``'s compiled code would make numba's cache load its numpy implementations,
    linear algebra included, into every process that loads the stepping loop: ``tests/test_fast_load.py``.)
    """
    lo, hi = 0, values.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if np.int64(values[mid]) < np.int64(value):
            lo = mid + 1
        else:
            hi = mid
    return lo


def longest_run(bounds: np.ndarray, run: np.ndarray, first: int, last: int) -> int:
    """Return the number of springs of the longest run among segments ``first:last`` (0 if none)."""
    longest = 0
    for s in range(first, last):
        if run[s]:
            longest = max(longest, np.int64(bounds[s + 1]) - np.int64(bounds[s]))
    return longest


def scatter_row(f: np.ndarray, pair: np.ndarray, c: int, a: int, shift: int, m: int) -> None:
    """Add coordinate ``c`` of a run's pair forces: ``f[a + t, c] += pair[c, t]``, ``f[a + shift + t, c] -=``.

    Where a particle is both ends (``shift < m``) it receives ``-f`` of spring ``p - b`` before
    ``+f`` of spring ``p - a``: the order of :func:`spring_range` over the run.
    """
    for t in range(min(shift, m)):  # particles with an i end only
        e = a + np.uint64(t)
        f[e, c] += pair[c, np.uint64(t)]
    for t in range(shift, m):  # both ends: -f of spring p - b, then +f of spring p - a
        e = a + np.uint64(t)
        f[e, c] = (f[e, c] - pair[c, np.uint64(t - shift)]) + pair[c, np.uint64(t)]
    for t in range(max(shift, m), shift + m):  # a j end only
        e = a + np.uint64(t)
        f[e, c] -= pair[c, np.uint64(t - shift)]


def plain_segment(x: np.ndarray, v: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray,
                  stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray, damped: int,
                  gaps: np.ndarray, g: int, start: int, stop: int, power: float) -> tuple[float, int]:
    """:func:`spring_range` over springs ``start:stop`` around their gap springs; return ``(power, g)``.

    ``gaps[g]`` is the first gap spring at or after ``start``; ``g`` returned, the first after ``stop``.
    """
    lo = np.int64(start)
    while True:  # (one call of spring_range in the code: each call site is compiled, inlined, again)
        gap = g < gaps.shape[0] and np.int64(gaps[g]) < np.int64(stop)
        hi = np.int64(gaps[g]) if gap else np.int64(stop)
        power = spring_range(x, v, f, i, j, stiffness, rest_length, damping, damped, lo, hi, power)
        if not gap:
            return power, g
        lo = hi + 1
        g += 1


def zero_gaps(pair: np.ndarray, rates: np.ndarray, damped: int, gaps: np.ndarray, g: int, q0: int,
              m: int) -> int:
    """Set the pair forces and powers of run ``q0 : q0 + m``'s gap springs to ``+0.0``; return the next ``g``.

    ``gaps[g]`` is the run's first gap spring. Adding ``+0.0`` leaves every force entry as it
    is (:func:`mslab.effects.spring_batches.gap_springs`), whatever the gap spring's ends.
    """
    zero = pair.dtype.type(0.0)
    while g < gaps.shape[0] and np.int64(gaps[g]) < np.int64(q0) + m:
        t = np.uint64(gaps[g]) - np.uint64(q0)
        pair[0, t] = pair[1, t] = pair[2, t] = zero
        if damped:
            rates[t] = zero
        g += 1
    return g


def spring_range(x: np.ndarray, v: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray,
                 stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray, damped: int,
                 start: int, stop: int, power: float) -> float:
    """Add the forces of springs ``start:stop`` to ``f``; return ``power`` plus their dissipated power.

    Spring by spring in scene order: ``f_i += s d``, ``f_j -= s d`` with ``s`` from
    :func:`pair_scale`. The coordinates are scalars for 1, 2 or 3 dimensions (kept in
    registers; the tests of ``dim`` and ``damped`` are the same for every spring and cost
    nothing measurable).
    """
    dim = x.shape[1]
    zero = x.dtype.type(0.0)  # 0 in the state's precision (a float64 literal would widen float32)
    for q in range(start, stop):
        a = i[q]
        b = j[q]
        dx = x[a, 0] - x[b, 0]
        dy = x[a, 1] - x[b, 1] if dim > 1 else zero
        dz = x[a, 2] - x[b, 2] if dim > 2 else zero
        rate = zero
        if damped:
            rate = dx * (v[a, 0] - v[b, 0])
            if dim > 1:
                rate += dy * (v[a, 1] - v[b, 1])
            if dim > 2:
                rate += dz * (v[a, 2] - v[b, 2])
        s, p = pair_scale(dx, dy, dz, rate, stiffness[q], rest_length[q], damping[q], damped)
        power += p
        f[a, 0] += s * dx
        f[b, 0] -= s * dx
        if dim > 1:
            f[a, 1] += s * dy
            f[b, 1] -= s * dy
        if dim > 2:
            f[a, 2] += s * dz
            f[b, 2] -= s * dz
    return power


def pair_scale(dx: float, dy: float, dz: float, rate: float, stiffness: float, rest_length: float,
               damping: float, damped: int) -> tuple[float, float]:
    """Return ``(s, p)``: a spring's force ``s d`` on ``i`` (``-s d`` on ``j``), its dissipated power ``p``.

    The one compiled statement of a spring's force (the class's formula, ``u = d / l``)::

        s = k (L / l - 1) - c (u . Δv) / l,   p = c (u . Δv)^2

    with ``d = x_i - x_j`` (``dx, dy, dz``; 0 for missing dimensions) and ``rate = d . Δv``
    (``Δv = v_i - v_j``; only read when ``damped``). This scale form has fewer operations
    between the loads of ``x`` and the stores into ``f`` than ``-k (d - L u)``, which bounds
    the loop (measured variant by variant, ``benchmarks/RESULTS.md``). A spring of zero
    length has ``1/l`` taken as 0 and exerts ``-k d = 0`` (never NaN). The constants take the
    precision of the coordinates (float32 stays float32). Cost: one square root, one division.
    """
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    one = type(length)(1.0)
    zero = type(length)(0.0)
    inv_l = one / length if length > zero else zero
    s = stiffness * (rest_length * inv_l - one)
    if damped:
        rate *= inv_l  # u . (v_i - v_j), the stretch rate
        cr = damping * rate
        return s - cr * inv_l, cr * rate
    return s, zero


def run_pair(x: np.ndarray, v: np.ndarray, a: int, b: int, t: int, k: float, rest: float, c: float,
             damped: int, out: np.ndarray, rates: np.ndarray) -> None:
    """Write spring ``t`` of a run: its pair force into ``out[:, t]``, its power into ``rates[t]``.

    The body of the run loops of :func:`spring_batch` (inlined there; ``damped`` a constant of
    each loop); the spring joins particles ``a + t`` and ``b + t``.
    """
    ta = a + t
    tb = b + t
    dx = x[ta, 0] - x[tb, 0]
    dy = x[ta, 1] - x[tb, 1]
    dz = x[ta, 2] - x[tb, 2]
    rate = x.dtype.type(0.0)
    if damped:
        rate = dx * (v[ta, 0] - v[tb, 0])
        rate += dy * (v[ta, 1] - v[tb, 1])
        rate += dz * (v[ta, 2] - v[tb, 2])
    scale, p = pair_scale(dx, dy, dz, rate, k, rest, c, damped)
    if damped:
        rates[t] = p
    out[0, t] = scale * dx
    out[1, t] = scale * dy
    out[2, t] = scale * dz


def lane_sum(values: np.ndarray, count: int = -1) -> float:
    """Return the sum of ``values[:count]`` (all if ``count < 0``) in eight lanes, lanes added pairwise.

    ``values[s]`` goes into lane ``s % 8``: eight independent running sums instead of one
    (whose every addition waits for the previous: about 1 ns a value); the order is fixed by the
    code, never by the machine or the compiler (no reassociation is allowed), so the result is the
    same everywhere. The lanes of whole rows of eight are :func:`mslab.lanes.eight_lanes` (compiled:
    one vector addition per row, the same additions in the same order), the rest goes to lane 0.
    """
    n = values.shape[0] if count < 0 else count
    body = n - n % 8
    s0, s1, s2, s3, s4, s5, s6, s7 = eight_lanes(values, body)
    for q in range(body, n):
        s0 += values[q]
    return ((s0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7))


def unit_vector(x: np.ndarray, a: int, b: int, u: np.ndarray) -> float:
    """Write ``u = (x_a - x_b) / l`` and return ``1 / l`` (``u = 0`` and 0 for a zero-length spring)."""
    length2 = 0.0
    for c in range(x.shape[1]):
        u[c] = x[a, c] - x[b, c]
        length2 += u[c] * u[c]
    length = np.sqrt(length2)
    inv_l = 1.0 / length if length > 0.0 else 0.0
    for c in range(x.shape[1]):
        u[c] *= inv_l
    return inv_l


def spring_jacobian_kernel(x: np.ndarray, v: np.ndarray, i: np.ndarray, j: np.ndarray,
                           stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray,
                           damped: int, bx: np.ndarray, bv: np.ndarray) -> None:
    """Fill the blocks ``bx[q] = df_i/dx_i`` and (``damped``) ``bv[q] = df_i/dv_i`` of every spring.

    The equations of :meth:`Springs.jacobians` (class docstring) as a loop, for the
    compiled Newton path (:mod:`mslab.fast.newton`); ``bx``, ``bv`` have shape (m, dim, dim).
    """
    dim = x.shape[1]
    u = np.empty(dim)
    dv = np.empty(dim)
    pdv = np.empty(dim)
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        inv_l = unit_vector(x, a, b, u)
        ratio = rest_length[q] * inv_l
        k = stiffness[q]
        rate = 0.0
        if damped:
            for c in range(dim):
                dv[c] = v[a, c] - v[b, c]
                rate += u[c] * dv[c]
            for c in range(dim):  # P_u dv = dv - u (u . dv)
                pdv[c] = dv[c] - u[c] * rate
        cl = damping[q] * inv_l
        for r in range(dim):
            for c in range(dim):
                uu = u[r] * u[c]
                proj = (1.0 if r == c else 0.0) - uu
                val = -k * (uu + (1.0 - ratio) * proj)
                if damped:
                    val -= cl * (u[r] * pdv[c] + rate * proj)
                    bv[q, r, c] = -damping[q] * uu
                bx[q, r, c] = val


def scatter_pair_blocks(blocks: np.ndarray, slot: np.ndarray, out: np.ndarray) -> None:
    """Add ``+B`` at (i, i), (j, j) and ``-B`` at (i, j), (j, i) into ``out`` (CSR data) at ``slot``.

    The order of :meth:`Springs._assemble`'s ``np.bincount`` (same sums, same order).
    """
    flat = blocks.ravel()
    m = flat.shape[0]
    for part in range(4):
        sign = 1.0 if part < 2 else -1.0
        base = part * m
        for e in range(m):
            out[slot[base + e]] += sign * flat[e]


def spring_energy_kernel(x: np.ndarray, i: np.ndarray, j: np.ndarray, stiffness: np.ndarray,
                         rest_length: np.ndarray) -> float:
    """Return the elastic energy ``sum_q k_q (l_q - L_q)^2 / 2`` (:meth:`Springs.energy`), springs in order.

    For the energy ledger's periodic check of a compiled run (:meth:`Springs.compiled_energy`):
    one pass, no temporary arrays (numpy's version gathers ``x[i] - x[j]`` and forms the unit
    vectors: 50-100 ms on a 300 x 300 cloth, a sixth of the steps between two checks). The sum
    runs in spring order, the same on every machine; it differs from numpy's pairwise sum by
    round-off. Cost: one square root per spring, ``O(n_springs)``.
    """
    dim = x.shape[1]
    energy = 0.0
    for q in range(i.shape[0]):
        a = i[q]
        b = j[q]
        length2 = 0.0
        for c in range(dim):
            d = x[a, c] - x[b, c]
            length2 += d * d
        stretch = np.sqrt(length2) - rest_length[q]
        energy += 0.5 * stiffness[q] * stretch * stretch
    return energy
