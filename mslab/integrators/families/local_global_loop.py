"""The fast mass-spring method's iterations in one compiled loop, one parallel launch per iteration.

With the global matrix's kept factors split among threads by the elimination tree
(:mod:`mslab.integrators.newton.tree_solve`), each thread owns the particles of its subtrees
and the serial *top* owns the last separators' particles. No spring joins two threads'
particles (a spring is an entry of the global matrix, and two subtrees of the tree share
none), so one iteration ``k`` is, per thread, in one parallel launch:

1. finish iteration ``k - 1``: the backward sweep of its subtrees (the top's was done) and
   the update of its particles (plain or Chebyshev:
   :func:`~mslab.integrators.families.local_step.update_row`);
2. start iteration ``k``: the local step of the springs that touch its particles, adding
   to its own particles only; their right-hand side rows; the forward sweep of its subtrees;

then, on the calling thread, the top: the local step for its particles (their springs, in
spring order), its right-hand side rows, its forward rows, its backward sweep and update.
The plain loop (:meth:`LocalGlobal.step`) launches three times per iteration and calls
from Python between them; here each particle still receives the same spring terms in
spring order and each solve the same operations in the same order, so **the iterates are
bitwise those of the plain loop**, for any number of threads (``tests/test_local_global_loop.py``).

Used by :meth:`LocalGlobal.step` when the global step has such factors, the scene is 3D,
and every force besides Hooke springs and linear drag is constant (gravity): forces that
vary with the iterate are evaluated by their effects in numpy, between launches.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.families.local_step import projection3, update_row
from mslab.integrators.newton.tree_kernels import backward_supernodes, forward_supernodes, top_solve
from mslab.jit import compiled, prange

if TYPE_CHECKING:
    from mslab.integrators.families.local_global import GlobalStep
    from mslab.integrators.newton.tree_solve import TreeSolve


class TreeIterations:
    """The scene renumbered for :func:`local_global_loop`: particles in the tree's order, springs by owner.

    Inside the loop particle ``slot[a]`` is row ``slot[a]`` of the permuted global matrix
    for a free particle, ``n_free + k`` for the ``k``-th pinned one: every sweep then reads
    memory in order, and a subtree's particles lie together. ``owner[slot]``: the thread
    (``0 .. bins-1``), -1 the top, -2 pinned. Springs ``ptr[t]:ptr[t+1]`` of the tables
    ``i, j, stiffness, rest_length`` (renumbered) touch thread ``t``'s particles, in
    increasing spring order; ``t = bins``: those touching the top's (a spring between a
    thread and the top is in both lists, each adding to its own end).
    """

    def __init__(self, g: GlobalStep, tree: TreeSolve, mass: np.ndarray):
        self.tree = tree
        bins = tree.bins
        n_particles = mass.size
        self.order = np.concatenate([g.free_idx[tree.perm], np.flatnonzero(g.pinned)]).astype(np.int64)
        slot = np.empty(n_particles, dtype=np.int64)
        slot[self.order] = np.arange(n_particles)
        self.owner = np.full(n_particles, -2, dtype=np.int64)
        self.owner[:tree.perm.size] = tree.owner
        i, j = slot[g.i], slot[g.j]
        lists = [np.flatnonzero((self.owner[i] == t) | (self.owner[j] == t)) for t in [*range(bins), -1]]
        springs = np.concatenate(lists).astype(np.int64)
        self.ptr = np.concatenate([[0], np.cumsum([s.size for s in lists])]).astype(np.int64)
        self.springs = (i[springs].astype(np.uint32), j[springs].astype(np.uint32),
                        np.ascontiguousarray(g.stiffness[springs]),
                        np.ascontiguousarray(g.rest_length[springs]))
        self.mass = np.ascontiguousarray(mass[self.order])
        self.extra = np.ascontiguousarray(g.constant[self.order])  # the constant forces (gravity)
        #: springs to pinned particles, rows in the tree's order: ``- h^2 L_fp y_p`` of the right side
        self.coupling = g.lap_fp[tree.perm] if g.lap_fp.nnz else None
        self.pinned = np.flatnonzero(g.pinned)
        self._loop = compiled(local_global_loop, "the iterations of fast_mass_spring", fastmath=False)

    def run(self, g: GlobalStep, xn: np.ndarray, vn: np.ndarray, dt: float, omega: np.ndarray, relax: float,
            chebyshev: bool, tol: float) -> tuple[np.ndarray, int]:
        """Run up to ``len(omega)`` iterations from ``y = x_n + h v_n``; return (positions, iterations done).

        ``tol < 0``: no early stop; else stop after the first iteration whose change is at most
        ``tol`` (absolute); a change that is not finite stops the loop too. Work done and
        discarded when it stops early: the next iteration's local step and forward sweeps.
        """
        t = self.tree
        y = xn + dt * vn
        n = self.order.size
        coupling = (self.coupling @ y[self.pinned] if self.coupling is not None
                    else np.zeros((t.perm.size, 3)))
        x = np.empty_like(y)
        work = (np.empty((n, 3)), np.empty((n, 3)), np.empty((t.perm.size, 3)), np.empty((t.perm.size, 3)),
                np.empty((n, 3)), np.zeros(t.bins + 1))
        done = self._loop(y, xn, x, self.order, self.mass, dt * g.gamma, coupling, self.coupling is not None,
                          self.springs, self.owner, self.ptr, self.extra, dt * dt, omega, relax, chebyshev,
                          tol, t.kernel_args(), t.nodes, t.offsets, t.top, work)
        return x, int(done)


# -- compiled (numba's subset of Python; helpers from local_step and tree_kernels compiled with it) --
def local_global_loop(y_in: np.ndarray, xn: np.ndarray, x_out: np.ndarray, order: np.ndarray,
                      mass: np.ndarray, h_gamma: float, coupling: np.ndarray, coupled: bool, springs: tuple,
                      owner: np.ndarray, ptr: np.ndarray, extra: np.ndarray, h2: float, omega: np.ndarray,
                      relax: float, chebyshev: bool, tol: float, tree: tuple, nodes: np.ndarray,
                      offsets: np.ndarray, top: np.ndarray, work: tuple) -> int:
    """Iterate from ``y_in`` (module docstring); write the last iterate to ``x_out``; return the iterations.

    Particles are renumbered by ``order`` inside (slot ``r`` holds particle ``order[r]``):
    ``x, prev = y`` and the constant right-hand side ``base = M y + h gamma x_n - h^2 L_fp
    y_p`` (``coupling`` = ``L_fp y_p``, used when ``coupled``), as :meth:`LocalGlobal._base`
    writes it. ``springs`` = (i, j, stiffness, rest_length) by list (:class:`TreeIterations`);
    ``tree`` = :meth:`TreeSolve.kernel_args <mslab.integrators.newton.tree_solve.TreeSolve.kernel_args>`;
    ``nodes[offsets[t]:offsets[t+1]]`` thread ``t``'s particles, ``top`` the top's;
    ``work`` = (x, prev, base, y, jd, changes): ``changes`` each thread's last change, then the top's.
    """
    x, prev, base_p, y, jd, changes = work
    n_free = base_p.shape[0]
    for r in range(order.shape[0]):
        a = order[r]
        for c in range(3):
            x[r, c] = y_in[a, c]
            prev[r, c] = y_in[a, c]
            if r < n_free:
                b = mass[r] * y_in[a, c] + h_gamma * xn[a, c]
                base_p[r, c] = b - h2 * coupling[r, c] if coupled else b
    done = iterate(x, prev, springs, owner, ptr, base_p, extra, h2, omega, relax, chebyshev, tol, tree, nodes,
                   offsets, top, y, jd, changes)
    for r in range(order.shape[0]):
        a = order[r]
        for c in range(3):
            x_out[a, c] = x[r, c]
    return done


def iterate(x: np.ndarray, prev: np.ndarray, springs: tuple, owner: np.ndarray, ptr: np.ndarray,
            base_p: np.ndarray, extra: np.ndarray, h2: float, omega: np.ndarray, relax: float,
            chebyshev: bool, tol: float, tree: tuple, nodes: np.ndarray, offsets: np.ndarray,
            top: np.ndarray, y: np.ndarray, jd: np.ndarray, changes: np.ndarray) -> int:
    """Iterate on the renumbered particles (module docstring); return how many iterations were done."""
    bins = offsets.shape[0] - 1
    iterations = omega.shape[0]
    done = 0
    for it in range(iterations + 1):
        finish = it > 0
        start = it < iterations
        w = omega[it - 1] if finish else 1.0
        if bins > 1:
            for t in prange(bins):
                changes[t] = thread_part(t, finish, start, x, prev, springs, owner, ptr, base_p, extra, h2, w,
                                         relax, chebyshev, tree, nodes, offsets, y, jd)
        else:
            changes[0] = thread_part(0, finish, start, x, prev, springs, owner, ptr, base_p, extra, h2, w,
                                     relax, chebyshev, tree, nodes, offsets, y, jd)
        if finish:
            done = it
            change = 0.0
            for t in range(bins + 1):
                change = worse(change, changes[t])
            if not np.isfinite(change) or change <= tol:
                break
        if not start:
            break
        # the top, on this thread: iteration it from its local step to its update
        for s in range(top.shape[0]):
            jd[top[s], 0] = 0.0
            jd[top[s], 1] = 0.0
            jd[top[s], 2] = 0.0
        local_part(bins, -1, x, springs, owner, ptr, jd)
        for s in range(top.shape[0]):
            right_side(top[s], base_p, extra, h2, jd, y)
        sn, rows, blk, tri, diagonal, sowner, _, _, top_sn, cptr, contrib, buffer, widest = tree
        top_solve(sn, rows, blk, tri, diagonal, sowner, top_sn, cptr, contrib, buffer, widest, y)
        top_change = 0.0
        for s in range(top.shape[0]):
            r = top[s]
            top_change = worse(top_change, update_row(x, prev, r, y, r, omega[it], relax, chebyshev))
        changes[bins] = top_change
    return done


def thread_part(t: int, finish: bool, start: bool, x: np.ndarray, prev: np.ndarray, springs: tuple,
                owner: np.ndarray, ptr: np.ndarray, base_p: np.ndarray, extra: np.ndarray, h2: float,
                omega: float, relax: float, chebyshev: bool, tree: tuple, nodes: np.ndarray,
                offsets: np.ndarray, y: np.ndarray, jd: np.ndarray) -> float:
    """Thread ``t``'s share of one launch: finish the last iteration, start the next; return its change."""
    sn, rows, blk, tri, diagonal, _, sn_order, sn_offsets, _, _, _, buffer, widest = tree
    first = offsets[t]
    last = offsets[t + 1]
    change = 0.0
    if finish:
        backward_supernodes(sn, rows, blk, tri, diagonal, sn_order, sn_offsets[t], sn_offsets[t + 1], widest,
                            y)
        for s in range(first, last):
            r = nodes[s]
            change = worse(change, update_row(x, prev, r, y, r, omega, relax, chebyshev))
    if start:
        for s in range(first, last):
            jd[nodes[s], 0] = 0.0
            jd[nodes[s], 1] = 0.0
            jd[nodes[s], 2] = 0.0
        local_part(t, t, x, springs, owner, ptr, jd)
        for s in range(first, last):
            right_side(nodes[s], base_p, extra, h2, jd, y)
        forward_supernodes(sn, rows, blk, tri, sn_order, sn_offsets[t], sn_offsets[t + 1], y, buffer)
    return change


def local_part(lst: int, who: int, x: np.ndarray, springs: tuple, owner: np.ndarray, ptr: np.ndarray,
               jd: np.ndarray) -> None:
    """Add the local step of spring list ``lst`` to the particles owned by ``who`` only, in spring order."""
    i, j, stiffness, rest_length = springs
    for q in range(ptr[lst], ptr[lst + 1]):
        a = i[q]
        b = j[q]
        moved, p0, p1, p2 = projection3(x, a, b, stiffness[q], rest_length[q])
        if moved:
            if owner[a] == who:
                jd[a, 0] += p0
                jd[a, 1] += p1
                jd[a, 2] += p2
            if owner[b] == who:
                jd[b, 0] -= p0
                jd[b, 1] -= p1
                jd[b, 2] -= p2


def right_side(r: int, base_p: np.ndarray, extra: np.ndarray, h2: float, jd: np.ndarray,
               y: np.ndarray) -> None:
    """Write row ``r`` of the global step's right-hand side: ``base + h^2 (J d + f_other)``."""
    y[r, 0] = base_p[r, 0] + h2 * (jd[r, 0] + extra[r, 0])
    y[r, 1] = base_p[r, 1] + h2 * (jd[r, 1] + extra[r, 1])
    y[r, 2] = base_p[r, 2] + h2 * (jd[r, 2] + extra[r, 2])


def worse(change: float, d: float) -> float:
    """Return the larger of two changes; NaN once either is not finite."""
    if not (np.isfinite(change) and np.isfinite(d)):
        return np.nan
    return max(change, d)
