"""The springs a ``SceneBuilder`` has collected: parameters, labels and duplicate detection.

A pair of particles joined twice (``[0, 1]`` twice, or ``[0, 1]`` and ``[1, 0]``) would
double the stiffness silently; it is refused in one line naming both entries, unless the
caller asks for ``duplicates = "merge"``: then the two become one spring with the summed
stiffness and damping and the stiffness-weighted rest length, which exerts exactly the
force of both (``k1 (l - L1) + k2 (l - L2) = (k1 + k2) (l - L)``).
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from mslab.errors import SceneError

#: spring kinds of scene files (sub-tables of ``[springs]``)
SPRING_KINDS = ("structural", "shear", "bend")


class SpringTable:
    """Flat lists of the springs added so far (global particle indices)."""

    def __init__(self) -> None:
        self.i: list[int] = []
        self.j: list[int] = []
        self.stiffness: list[float] = []
        self.rest_length: list[float] = []
        self.damping: list[float] = []
        self.kind: list[str] = []
        self._index: dict[int, int] = {}  # (min, max) pair key -> spring index
        self._batches: list[tuple[int, str, bool, int]] = []  # (first spring, where, explicit, pairs offset)
        self._open_batch = -1  # len(_batches) after add_one opened its batch (it adds to it since)

    def label(self, q: int) -> str:
        """Where spring ``q`` came from: ``springs.shear.pairs[3]``, or ``spring 7`` from the builder."""
        b = bisect.bisect_right([s for s, _, _, _ in self._batches], q) - 1
        start, where, explicit, offset = self._batches[b]
        pair = f"[{self.i[q] - offset}, {self.j[q] - offset}]"
        if explicit:
            return f"{where}pairs[{q - start}] = {pair}"
        if where != "springs.":
            return f"{where.rstrip('.')} (generated pair {q - start}: {pair})"
        return f"spring {q} ({pair})"

    def add(self, values: dict, x: np.ndarray, kind: str, where: str, explicit: bool,
            offset: int = 0) -> np.ndarray:
        """Add checked springs; returns their indices (merged duplicates give the earlier index).

        ``where`` prefixes error keys (``springs.structural.``); ``explicit``: the pairs were
        listed (errors name ``pairs[s]``) rather than generated; ``offset``: index of the
        body's first particle (messages show pairs in the body's numbering).
        """
        pairs = np.asarray(values["pairs"], dtype=np.int64).reshape(-1, 2)
        m = pairs.shape[0]
        lengths = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
        rest = values["rest_length"]
        if rest is None:
            zero = np.flatnonzero(lengths == 0.0)
            if zero.size:
                i, j = pairs[zero[0]]
                raise SceneError(f"{where}rest_length", f"spring [{i}, {j}] has zero length in the initial "
                                 "positions, so its rest length cannot be taken from them; "
                                 "give rest_length explicitly")
            rest = lengths
        rest = np.asarray(rest, dtype=float)
        if rest.ndim == 0:
            rest = np.full(m, float(rest))
        elif rest.shape != (m,):
            raise SceneError(f"{where}rest_length", f"must be one number or a list of {m} numbers "
                             f"(one per spring), got a list of {rest.shape[0]}")
        lo = np.minimum(pairs[:, 0], pairs[:, 1])
        hi = np.maximum(pairs[:, 0], pairs[:, 1])
        keys = (lo << 32) | hi
        start = len(self.i)
        self._batches.append((start, where, explicit, offset))
        clash = self._first_duplicate(keys, start)
        if clash is None:  # the common case: append everything at once
            self._append(pairs, values, rest, kind)
            self._index.update(zip(keys.tolist(), range(start, start + m), strict=True))
            return np.arange(start, start + m)
        if values["duplicates"] != "merge":
            s, q = clash
            self._append(pairs[: s + 1], values, rest[: s + 1], kind)  # so that labels can name both
            first = self.label(q)
            second = (f"[{pairs[s, 0] - offset}, {pairs[s, 1] - offset}]" if explicit
                      else self.label(start + s))
            for column in (self.i, self.j, self.stiffness, self.rest_length, self.damping, self.kind):
                del column[start:]
            self._batches.pop()
            key = f"{where}pairs[{s}]" if explicit else where.rstrip(".")
            raise SceneError(key, f"{second} joins the same two particles as {first}; remove one, or set "
                             "duplicates = \"merge\" to make them one spring with the summed stiffness")
        out = np.empty(m, dtype=np.int64)
        for s in range(m):  # merge one by one
            q = self._index.get(int(keys[s]))
            if q is None:
                q = len(self.i)
                self._append(pairs[s: s + 1], values, rest[s: s + 1], kind)
                self._index[int(keys[s])] = q
            else:
                k_old, k_new = self.stiffness[q], values["stiffness"]
                total = k_old + k_new
                if total > 0:
                    self.rest_length[q] = (k_old * self.rest_length[q] + k_new * rest[s]) / total
                self.stiffness[q] = total
                self.damping[q] += values["damping"]
            out[s] = q
        return out

    def add_one(self, i: int, j: int, stiffness: float, rest_length: float | None, damping: float,
                kind: str, xi: list[float], xj: list[float]) -> int | None:
        """Add one checked builder spring in O(1); None when :meth:`add` must handle it.

        That is a pair joined already (an error, or a merge) or a zero length with no
        rest length (an error): :meth:`add` raises or merges as for any batch. ``xi``, ``xj``:
        the positions of ``i`` and ``j`` (the rest length is computed as :meth:`add` does).
        """
        key = (i << 32) | j if i < j else (j << 32) | i
        if key in self._index:
            return None
        if rest_length is None:  # the sum in numpy's order: sqrt((d0^2 + d1^2) + d2^2)
            squares = 0.0
            for a, b in zip(xi, xj, strict=True):
                d = a - b
                squares += d * d
            rest_length = math.sqrt(squares)
            if rest_length == 0.0:
                return None
        q = len(self.i)
        if self._open_batch != len(self._batches):  # the last batch is not one of these: open one
            self._batches.append((q, "springs.", False, 0))
            self._open_batch = len(self._batches)
        self._index[key] = q
        self.i.append(i)
        self.j.append(j)
        self.stiffness.append(stiffness)
        self.rest_length.append(rest_length)
        self.damping.append(damping)
        self.kind.append(kind)
        return q

    def _first_duplicate(self, keys: np.ndarray, start: int) -> tuple[int, int] | None:
        """``(s, q)``: the first new pair ``s`` that spring ``q`` (earlier) already joins, or None."""
        m = keys.shape[0]
        hits = np.fromiter((self._index.get(k, -1) for k in keys.tolist()), dtype=np.int64, count=m) \
            if self._index else np.full(m, -1, dtype=np.int64)
        _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
        earlier = first[inverse.ravel()]
        bad = np.flatnonzero((hits >= 0) | (earlier != np.arange(m)))
        if bad.size == 0:
            return None
        s = int(bad[0])
        return s, int(hits[s]) if hits[s] >= 0 else start + int(earlier[s])

    def _append(self, pairs: np.ndarray, values: dict, rest: np.ndarray, kind: str) -> None:
        m = pairs.shape[0]
        self.i.extend(pairs[:, 0].tolist())
        self.j.extend(pairs[:, 1].tolist())
        self.stiffness.extend([float(values["stiffness"])] * m)
        self.damping.extend([float(values["damping"])] * m)
        self.rest_length.extend(rest.tolist())
        self.kind.extend([kind] * m)
