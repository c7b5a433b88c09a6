"""Hooke springs with optional damping along the spring (lecture notes, eqs. 1-2).

The numpy methods of :class:`Springs` are the reference; the compiled loops of the same
equations are in :mod:`mslab.effects.spring_kernels` (numba-compatible style). Spring sets are
recorded by :mod:`mslab.effects.spring_table` (duplicates, rest lengths, labels).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from mslab.effects.base import Body, BuildContext, Builder, Effect, HookeSprings
from mslab.effects.registry import register
from mslab.effects.schema import Key, check_keys
from mslab.effects.spring_batches import batches, gap_springs, run_flags, segments
from mslab.effects.spring_kernels import (
    scatter_pair_blocks,
    spring_energy_kernel,
    spring_jacobian_kernel,
    spring_kernel,
)
from mslab.effects.spring_kick import spring_kernel_kick
from mslab.effects.spring_table import SPRING_KINDS, SpringTable
from mslab.lanes import state_sums

if TYPE_CHECKING:  # scipy.sparse is imported on first use: `import mslab` stays cheap
    from collections.abc import Callable

    import numpy.typing as npt
    import scipy.sparse as sp


def scatter_pairs(f: np.ndarray, i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """Sum pair forces ``+f`` onto particles ``i`` and ``-f`` onto ``j`` -> (n, dim)."""
    out = np.empty((n, f.shape[1]))
    for k in range(f.shape[1]):
        out[:, k] = np.bincount(i, f[:, k], minlength=n) - np.bincount(j, f[:, k], minlength=n)
    return out


_INTEGERS = (int, np.integer)
_NUMBERS = (int, float, np.integer, np.floating)
_BOOLS = (bool, np.bool_)


def _per_spring(value: npt.ArrayLike, name: str, m: int) -> np.ndarray:
    """One float per spring: an array of ``m`` values, or one value for every spring."""
    array = np.asarray(value, dtype=float)
    if array.ndim > 1 or array.size not in (1, m):
        raise ValueError(f"Springs: {name} needs one value or one per spring ({m}), got shape {array.shape}")
    return np.array(np.broadcast_to(array.reshape(-1)[:m] if array.ndim else array, (m,)))  # own, writable


def _index(value: object, n: int) -> bool:
    """``value`` is a particle index in ``0..n-1`` (as the schema's ``index`` accepts)."""
    return isinstance(value, _INTEGERS) and not isinstance(value, _BOOLS) and 0 <= value < n


def _non_negative(value: object) -> bool:
    """``value`` is a finite number >= 0 (as the schema's ``number`` with ``low=0`` accepts)."""
    return (isinstance(value, _NUMBERS) and not isinstance(value, _BOOLS) and math.isfinite(value)
            and value >= 0.0)


@register
class Springs(Effect):
    """A set of Hooke springs between particle pairs.

    For the spring ``q`` joining ``i`` and ``j`` with ``d = x_i - x_j``, current length
    ``l = |d|``, unit direction ``u = d / l``, rest length ``L`` and stiffness ``k``
    (lecture notes, eq. 2), plus damping ``c`` acting on the stretch rate ``u . (v_i - v_j)``::

        f_i = k (L - l) u - c (u . (v_i - v_j)) u,      f_j = -f_i

    Energy ``U = sum_q k (l - L)^2 / 2``; dissipated power ``P = sum_q c (u . Δv)^2``.
    Jacobian blocks (``P_u = I - u u^T``)::

        df_i/dx_i = -k [ u u^T + (1 - L/l) P_u ]  -  c/l [ u (P_u Δv)^T + (u.Δv) P_u ]
        df_i/dv_i = -c u u^T

    A spring of zero current length exerts no force (``f_i = -k (d - L u)`` with ``u = 0``),
    never NaN; its Jacobian there is taken as ``-k I`` (the zero-rest-length limit).

    Parameters
    ----------
    springs : ndarray of int, shape (n_springs, 2)
    stiffness, rest_length, damping : ndarray, shape (n_springs,)
    n_particles : int
    kind : ndarray of str, shape (n_springs,), optional
        A label per spring (``structural``, ``shear``, ``bend`` ...).
    """

    name = "springs"
    section = "springs"
    per_body = True
    kinds = SPRING_KINDS
    keys = (
        Key("pairs", "pairs", default=None, default_doc="from the generator",
            doc="which particles the springs join (indices within the body); "
                "required with explicit positions"),
        Key("stiffness", low=0.0, unit="N/m", doc="Hooke stiffness k"),
        Key("damping", default=0.0, low=0.0, unit="N s/m", doc="damping c along the spring"),
        Key("rest_length", "numbers", default=None, low=0.0, unit="m", per="pairs",
            default_doc="the initial length",
            doc="length at which a spring is relaxed (one, or one per spring)"),
        Key("duplicates", "string", default="error", choices=("error", "merge"),
            doc='a pair joined twice is an error; "merge" makes it one spring with the summed '
                "stiffness and damping"),
    )
    builder_methods = ("add_springs", "add_spring")
    order = 10
    internal = True
    summary = ("Hooke springs with damping along each spring; one table per kind "
               "(`structural`, `shear`, `bend`)")
    kernel = staticmethod(spring_kernel)
    kick_kernel = staticmethod(spring_kernel_kick)

    dissipative = False
    velocity_dependent = False

    def __init__(self, springs: npt.ArrayLike, stiffness: npt.ArrayLike, rest_length: npt.ArrayLike,
                 damping: npt.ArrayLike, n_particles: int, kind: npt.ArrayLike | None = None):
        self.springs = np.asarray(springs, dtype=np.int64).reshape(-1, 2)
        self.i = np.ascontiguousarray(self.springs[:, 0])
        self.j = np.ascontiguousarray(self.springs[:, 1])
        self.stiffness, self.rest_length, self.damping = (
            _per_spring(value, name, self.i.size)
            for value, name in ((stiffness, "stiffness"), (rest_length, "rest_length"), (damping, "damping")))
        self.kind = np.array(["structural"] * len(self.i) if kind is None else kind, dtype=str)
        self.n = int(n_particles)
        self._batched: tuple | None = None  # kernel_params, on first use
        damped = bool(np.any(self.damping != 0.0))
        self.velocity_dependent = damped
        self.dissipative = damped
        self.conservative = True  # the Hooke part has a potential; damping is booked as power
        self._csr = None  # Jacobian sparsity pattern, built on first use (see _assemble)

    # -- physics ---------------------------------------------------------------------------------
    def _geometry(self, x: np.ndarray):
        d = x[self.i] - x[self.j]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        safe = np.where(length > 0.0, length, 1.0)
        u = np.where((length > 0.0)[:, None], d / safe[:, None], 0.0)
        return d, length, u

    def _pair_force(self, x: np.ndarray, v: np.ndarray):
        d, length, u = self._geometry(x)
        f = -self.stiffness[:, None] * (d - self.rest_length[:, None] * u)
        if not self.dissipative:
            return f, 0.0
        rate = np.einsum("ij,ij->i", u, v[self.i] - v[self.j])
        f -= (self.damping * rate)[:, None] * u
        return f, float(np.sum(self.damping * rate * rate))

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Return the spring forces, shape (n_particles, dim)."""
        f, _ = self._pair_force(x, v)
        return scatter_pairs(f, self.i, self.j, self.n)

    def force_and_power(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Return the forces and the power dissipated by the damping, from one pass."""
        f, p = self._pair_force(x, v)
        return scatter_pairs(f, self.i, self.j, self.n), p

    def power(self, x: np.ndarray, v: np.ndarray) -> float:
        """Return the power dissipated by the damping along the springs, ``sum_q c (u . Δv)^2``."""
        return self._pair_force(x, v)[1]

    def energy(self, x: np.ndarray) -> float:
        """Return the elastic energy ``sum_q k (l - L)^2 / 2``."""
        _, length, _ = self._geometry(x)
        return float(0.5 * np.sum(self.stiffness * (length - self.rest_length) ** 2))

    def energies(self, xs: np.ndarray) -> np.ndarray:
        """:meth:`energy` of each state of ``xs`` (k, n, dim), bitwise: the terms of all states at once.

        The same elementwise operations as :meth:`energy`, then one numpy sum per state
        (:func:`mslab.lanes.state_sums`). A subclass with an ``energy`` of its own gets that,
        state by state.
        """
        if type(self).energy is not Springs.energy:
            return super().energies(xs)
        d = xs[:, self.i] - xs[:, self.j]
        terms = self.stiffness * (np.sqrt(np.einsum("kij,kij->ki", d, d)) - self.rest_length) ** 2
        return 0.5 * state_sums(terms)

    def compiled_energy(self, x: np.ndarray) -> float:
        """:meth:`energy` through :func:`spring_energy_kernel` (compiled; round-off apart the same)."""
        from mslab.jit import available, compiled

        if not available() or type(self).energy is not Springs.energy:  # a subclass's own energy
            return self.energy(x)
        x = np.ascontiguousarray(x, dtype=float)
        return float(compiled(spring_energy_kernel)(x, self.i, self.j, self.stiffness, self.rest_length))

    def lengths(self, x: np.ndarray) -> np.ndarray:
        """Return the current spring lengths, shape (n_springs,)."""
        return self._geometry(x)[1]

    def jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix | None]:
        """Return ``(df/dx, df/dv)`` from the blocks of the class docstring (df/dv None undamped)."""
        d, length, u = self._geometry(x)
        dim = x.shape[1]
        eye = np.eye(dim)[None]
        uu = u[:, :, None] * u[:, None, :]
        proj = eye - uu
        ratio = np.where(length > 0.0, self.rest_length / np.where(length > 0, length, 1.0), 0.0)
        bx = -self.stiffness[:, None, None] * (uu + (1.0 - ratio)[:, None, None] * proj)
        dfdv = None
        if self.dissipative:
            dv = v[self.i] - v[self.j]
            rate = np.einsum("ij,ij->i", u, dv)
            pdv = np.einsum("kab,kb->ka", proj, dv)
            inv_l = np.where(length > 0.0, 1.0 / np.where(length > 0, length, 1.0), 0.0)
            c = (self.damping * inv_l)[:, None, None]
            bx = bx - c * (u[:, :, None] * pdv[:, None, :] + rate[:, None, None] * proj)
            dfdv = self._assemble(-self.damping[:, None, None] * uu)
        return self._assemble(bx), dfdv

    def compiled_jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix | None]:
        """:meth:`jacobians` through :func:`spring_jacobian_kernel` (compiled by numba on first use)."""
        from mslab.jit import compiled

        dim = x.shape[1]
        m = self.i.shape[0]
        bx = np.empty((m, dim, dim))
        bv = np.empty((m, dim, dim) if self.dissipative else (0, dim, dim))
        x, v = np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(v, dtype=float)
        compiled(spring_jacobian_kernel)(x, v, self.i, self.j, self.stiffness, self.rest_length, self.damping,
                                         int(self.dissipative), bx, bv)
        return (self._assemble(bx, compiled(scatter_pair_blocks)),
                self._assemble(bv, compiled(scatter_pair_blocks)) if self.dissipative else None)

    def _assemble(self, blocks: np.ndarray, scatter: Callable | None = None) -> sp.csr_matrix:
        """Assemble like ``mslab.effects.base.pair_blocks(blocks, i, j, n)``, into a CSR pattern reused.

        The sparsity pattern of a spring Jacobian never changes, so the sorting of a
        COO -> CSR conversion is done on the first call only: later calls sum the block
        entries into the stored slots (``np.bincount`` over a precomputed index map).
        """
        import scipy.sparse as sp  # on first use: `import mslab` stays cheap

        m, dim, _ = blocks.shape
        if self._csr is None or self._csr[0] != dim:
            self._csr = (dim,) + self._pattern(dim)
        _, slot, indices, indptr = self._csr
        size = self.n * dim
        if scatter is None:
            b = blocks.ravel()
            data = np.bincount(slot, weights=np.concatenate([b, b, -b, -b]), minlength=indices.size)
        else:  # the compiled loop of the same sums
            data = np.zeros(indices.size)
            scatter(blocks, slot, data)
        return sp.csr_matrix((data, indices, indptr), shape=(size, size))

    def _pattern(self, dim: int):
        """Slot of every block entry (the order of ``_assemble``'s data), CSR indices, indptr."""
        size = self.n * dim
        ri = self.i[:, None] * dim + np.arange(dim)[None, :]
        rj = self.j[:, None] * dim + np.arange(dim)[None, :]

        # (row, col) of each entry of the blocks, in blocks.ravel() order
        def grid(a: np.ndarray, b: np.ndarray):
            return np.repeat(a, dim, axis=1).ravel(), np.tile(b, (1, dim)).ravel()

        # +B at (i, i) and (j, j), then -B at (i, j) and (j, i), as pair_blocks
        pairs = [grid(ri, ri), grid(rj, rj), grid(ri, rj), grid(rj, ri)]
        rows = np.concatenate([p[0] for p in pairs])
        cols = np.concatenate([p[1] for p in pairs])
        keys, slot = np.unique(rows * size + cols, return_inverse=True)
        indptr = np.searchsorted(keys // size, np.arange(size + 1)).astype(np.int32)
        return slot, (keys % size).astype(np.int32), indptr

    def hooke_springs(self) -> HookeSprings:
        """Return ``(i, j, k, L, kind)`` (capability: Hooke springs; the damping is this effect's own)."""
        return HookeSprings(self.i, self.j, self.stiffness, self.rest_length, self.kind)

    def kernel_params(self) -> tuple:
        """Return the parameters of :func:`spring_kernel` (after ``x, v, f``).

        ``(i, j, stiffness, rest_length, damping, damped, bounds, run, batches, phases, gaps)``:
        the spring arrays in the order of their conflict-free batches
        (:func:`mslab.effects.spring_batches.batches`), rows joined by gap springs (their
        indices ``gaps``, ascending: no force; :func:`~mslab.effects.spring_batches.gap_springs`),
        each batch cut into runs and plain segments
        (:func:`~mslab.effects.spring_batches.segments`), a run's entry in ``run`` telling
        whether it has one stiffness and damping (:func:`~mslab.effects.spring_batches.run_flags`);
        computed once per effect. The springs themselves are :attr:`i`, :attr:`j`, ...:
        ``np.delete(i, gaps)`` is a permutation of them.
        """
        if self._batched is None:
            order, ranges, phases = batches(self.i, self.j, self.n)
            take, step, ranges = gap_springs(self.i[order], self.j[order], ranges)
            order = order[take]
            i, j = self.i[order] + step, self.j[order] + step
            bounds, run, batch_segments = segments(i, j, ranges)
            k, rest, c = self.stiffness[order], self.rest_length[order], self.damping[order]
            run = run_flags(bounds, run, k, c)
            gaps = np.flatnonzero(step)
            self._batched = (i, j, k, rest, c, int(self.dissipative), bounds, run, batch_segments, phases,
                             gaps)
        return self._batched

    # -- scene description -----------------------------------------------------------------------
    @staticmethod
    def add_springs(builder: Builder, pairs: npt.ArrayLike, stiffness: float,
                    rest_length: npt.ArrayLike | None = None, damping: float = 0.0,
                    kind: str = "structural", duplicates: str = "error") -> np.ndarray:
        """Add springs for every ``(i, j)`` in ``pairs`` with the same parameters; return their indices.

        ``rest_length``: one number, one per pair, or None (each spring's current length).
        A pair joined twice (in either order) is an error unless ``duplicates="merge"``,
        which makes it one spring with the summed stiffness and damping.
        """
        raw = {"pairs": pairs, "stiffness": stiffness, "rest_length": rest_length, "damping": damping,
               "duplicates": duplicates}
        values = builder.check_effect(Springs, raw, "springs.")
        if values["pairs"] is None:
            raise builder.error("springs.pairs", "missing: a list of [i, j] index pairs")
        return Springs._table(builder).add(values, builder.positions(), kind, "springs.", explicit=False)

    @staticmethod
    def add_spring(builder: Builder, i: int, j: int, stiffness: float, rest_length: float | None = None,
                   damping: float = 0.0, kind: str = "structural", duplicates: str = "error") -> int:
        """Add a spring between particles i and j; ``rest_length=None`` takes the current length.

        Returns the spring's index (see :meth:`add_springs` for ``duplicates``). O(1): plain
        values are checked here and the spring appended; anything else (a mistake, a
        duplicate) takes the path of :meth:`add_springs`, which names it.
        """
        n = builder.n_particles
        if (_index(i, n) and _index(j, n) and i != j and _non_negative(stiffness) and _non_negative(damping)
                and (rest_length is None or _non_negative(rest_length)) and isinstance(kind, str)
                and duplicates in ("error", "merge")):
            x = builder.positions()
            q = Springs._table(builder).add_one(int(i), int(j), float(stiffness),
                                                None if rest_length is None else float(rest_length),
                                                float(damping), kind, x[i].tolist(), x[j].tolist())
            if q is not None:
                return q
        added = Springs.add_springs(builder, [[i, j]], stiffness, rest_length, damping, kind, duplicates)
        return int(added[0])

    @staticmethod
    def _table(builder: Builder) -> SpringTable:
        entries = builder.entries(Springs)
        if not entries:
            entries.append(SpringTable())
        return entries[0]

    @classmethod
    def from_toml(cls, builder: Builder, raw: dict, prefix: str, body: Body | None = None) -> None:
        """Read the ``[springs.<kind>]`` tables of one body: pairs within the body, or from its generator."""
        table = builder.check_table(raw, prefix.rstrip("."))
        check_keys(table, cls.kinds, prefix, "spring kind")
        for kind, sub in table.items():
            where = f"{prefix}{kind}."
            sub = builder.check_table(sub, where.rstrip("."))
            values = builder.check_effect(cls, sub, where, n=body.n)
            explicit = values["pairs"] is not None
            if not explicit:
                if body.generator is None:
                    raise builder.error(f"{where}pairs", "missing: with explicit positions, list the springs "
                                        "as pairs = [[i, j], ...]")
                values["pairs"] = body.generated_pairs(kind)
                if values["pairs"].shape[0] == 0:
                    raise builder.error(f"springs.{kind}",
                                        f"generator '{body.generator}' has no {kind} springs")
            values["pairs"] = values["pairs"] + body.first
            cls._table(builder).add(values, builder.positions(), kind, where, explicit, body.first)

    @classmethod
    def build(cls, entries: list, ctx: BuildContext) -> list[Effect]:
        """Return one :class:`Springs` holding every spring of the scene (none when there are none)."""
        table = entries[0]
        if not table.i:
            return []
        pairs = np.stack([np.array(table.i, dtype=np.int64), np.array(table.j, dtype=np.int64)], axis=1)
        return [cls(pairs, np.array(table.stiffness), np.array(table.rest_length),
                    np.array(table.damping), ctx.n_particles,
                    np.array(table.kind, dtype=str))]

    @classmethod
    def example(cls, dim: int) -> dict:
        """Return springs among 6 particles for the registry-wide tests."""
        return {"pairs": [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [0, 5], [1, 4]], "stiffness": 40.0,
                "damping": 0.5, "rest_length": 0.7}

    @classmethod
    def toml_fragment(cls, values: dict) -> dict:
        """Return ``values`` as a ``[springs.structural]`` table."""
        return {"springs": {"structural": values}}

    def __repr__(self):
        return f"Springs(n_springs={len(self.springs)})"
