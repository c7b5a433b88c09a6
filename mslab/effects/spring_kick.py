"""The springs' kernel followed by the kick pass, block by block: one parallel launch fewer a step.

A step of the splitting loop with an explicit kick (symplectic Euler, the frame loop's method)
evaluates the forces and then makes one pass over the particles (:func:`mslab.kicks.kick`).
On a scene whose springs run in two parallel phases (:mod:`mslab.effects.spring_batches`),
that is three launches of the threads a step: each costs the wake-up of the sleeping
threads (46 us on the 2-vCPU machine of ``benchmarks/RESULTS.md``). Here the pass joins the
springs' second phase: once odd batch ``k`` (blocks ``2k+1`` and ``2k+2``) is summed, those
blocks' forces are complete (their even batches ran in the first phase, no far batch is
left), and no other batch of the phase reads them, so the same thread kicks them at once.
Each entry gets the same operations in the same order as in the separate pass, and each
spring's force the same sums: the results are bitwise those of the kernel and the pass,
on any number of threads (``tests/test_fused_kick.py``). (A run's vector loop may read up to
7 particles past its run, whose pair forces it computes and drops: where those lie in a block
another thread is kicking, what it reads is discarded either way.)
"""

from __future__ import annotations

import numpy as np

from mslab.effects.spring_kernels import spring_batch, spring_kernel
from mslab.jit import prange
from mslab.kicks import kick


def spring_kernel_kick(x: np.ndarray, v: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray,
                       stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray, damped: int,
                       bounds: np.ndarray, run: np.ndarray, batches: np.ndarray, phases: np.ndarray,
                       gaps: np.ndarray, xf: np.ndarray, vf: np.ndarray, ff: np.ndarray, f0f: np.ndarray,
                       w: np.ndarray, h: float, hd: float, limit: float) -> tuple[float, int]:
    """Add the spring forces to ``f``, then kick: return ``(power, bad)``; ``bad = -1``: not kicked.

    :func:`mslab.effects.spring_kernels.spring_kernel` (the arguments up to ``gaps``), then
    :func:`mslab.kicks.kick` over all particles (``xf .. limit``: flat views of the loop's
    coordinate-major arrays, ``f`` among them), the blocks of odd batch ``k`` kicked in its
    iteration of the second phase (block 0 with batch 0). Where the springs are not in two
    parallel phases with an empty far batch (a small scene: one batch), only the forces are
    added and ``bad = -1`` asks the caller for the pass. Cost: the kernel's and the pass's,
    in two launches instead of three.
    """
    n_phases = phases.shape[0] - 1
    blocks = phases[2] if n_phases == 3 else 0
    if blocks < 4 or batches[blocks + 1] != batches[blocks]:  # (a far batch: forces change after)
        return spring_kernel(x, v, f, i, j, stiffness, rest_length, damping, damped, bounds, run,
                             batches, phases, gaps), -1
    n_batches = batches.shape[0] - 1
    powers = np.empty(n_batches)
    for r in prange(phases[0], phases[1]):
        powers[r] = spring_batch(x, v, f, i, j, stiffness, rest_length, damping, damped, bounds, run, gaps,
                                 batches[r], batches[r + 1])
    powers[blocks] = spring_batch(x, v, f, i, j, stiffness, rest_length, damping, damped, bounds, run, gaps,
                                  batches[blocks], batches[blocks + 1])  # the (empty) far batch
    first = phases[1]
    n = x.shape[0]
    bad = np.empty(phases[2] - first, np.int64)
    for r in prange(first, phases[2]):
        powers[r] = spring_batch(x, v, f, i, j, stiffness, rest_length, damping, damped, bounds, run, gaps,
                                 batches[r], batches[r + 1])
        k = r - first  # odd batch k joins blocks 2k+1 and 2k+2: their forces are complete
        lo = 0 if k == 0 else 2 * k + 1
        hi = min(2 * k + 3, blocks)
        p0 = (lo * n + blocks - 1) // blocks  # a block's first particle p: p * blocks // n == block
        p1 = (hi * n + blocks - 1) // blocks
        count = 0
        for c in range(x.shape[1]):
            e0 = c * n + p0
            e1 = c * n + p1
            count += kick(xf[e0:e1], vf[e0:e1], ff[e0:e1], f0f[e0:e1], w[e0:e1], h, hd, limit)
        bad[k] = count
    power = 0.0
    for r in range(n_batches):
        power += powers[r]
    total = 0
    for k in range(bad.shape[0]):
        total += bad[k]
    return power, total
