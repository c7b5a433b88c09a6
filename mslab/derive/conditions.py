"""Orders from the rooted-tree order conditions ``Phi(t) = 1/gamma(t)``.

Runge-Kutta tableau ``A, b`` (explicit or implicit): the elementary weight of a tree is
``Phi(t) = b^T u(t)`` with the stage vector ``u(t) = prod_children (A u(child))``
(elementwise product; ``u(leaf) = 1``). The method has order ``p`` when
``Phi(t) = 1/gamma(t)`` for every tree with at most ``p`` vertices (Butcher's theorem;
Hairer-Nørsett-Wanner I, Theorem II.2.13). The conditions read ``A`` only, as for
autonomous systems ``y' = F(y)`` (mslab's forces carry no explicit time), so ``c`` plays no
part.

Splitting ``x += a_0 h v; v += b_0 h a(x); x += a_1 h v; ...; x += a_k h v`` on
``x' = v, v' = a(x)``: a partitioned Runge-Kutta method whose drift stage ``i`` sees the
kicks ``j < i`` and whose kick ``j`` sees the drifts ``i <= j``. Its conditions run over
the Nyström trees (colours alternate, drift vertices have at most one child), the trees
whose elementary differentials do not vanish for this problem (Hairer-Nørsett-Wanner I,
sec. II.14; Hairer-Lubich-Wanner, *Geometric Numerical Integration*, sec. III.2). Both
components need every tree with at most ``p`` vertices.

Stage vectors are memoised per tree; exact coefficients are evaluated exactly, floats in
floating point with a round-off bound per condition (see ``Arithmetic.satisfied``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from mslab.derive.coefficients import Arithmetic
from mslab.derive.trees import density, nystrom_trees, plain, size, trees


class OrderAboveLimit(Exception):
    """Every condition through ``max_order + 1`` holds."""


class _Weights:
    """Elementary weights of coloured trees ``(colour, children)``.

    ``weights[colour]``: the output weights of a root of that colour; ``coupling[(p, c)]``:
    the matrix from a child of colour ``c`` into the stages of a parent of colour ``p``.
    """

    def __init__(self, arith: Arithmetic, weights: dict, coupling: dict) -> None:
        self.arith = arith
        self.exact = arith.is_exact
        if self.exact:
            self.weights = weights
            self.coupling = {key: [[(j, m) for j, m in enumerate(row) if m != arith.zero] for row in matrix]
                             for key, matrix in coupling.items()}
        else:
            self.weights = {k: np.asarray(w, dtype=float) for k, w in weights.items()}
            self.abs_weights = {k: np.abs(w) for k, w in self.weights.items()}
            self.coupling = {k: np.asarray(m, dtype=float).reshape(len(self.weights[k[0]]),
                                                                   len(self.weights[k[1]]))
                             for k, m in coupling.items()}
            self.abs_coupling = {k: np.abs(m) for k, m in self.coupling.items()}
        self._memo: dict = {}
        self._carried: dict = {}

    def _stage(self, tree: tuple):
        """``u(t)`` over the stages of the root's colour (and ``|u|(t)`` for floats)."""
        if tree in self._memo:
            return self._memo[tree]
        colour, children = tree
        n = len(self.weights[colour])
        if self.exact:
            u = [self.arith.one] * n
            for child in children:
                u = [ui * wi for ui, wi in zip(u, self._into(colour, child), strict=True)]
            out = u
        else:
            u, ua = np.ones(n), np.ones(n)
            for child in children:
                cw, cwa = self._into(colour, child)
                u, ua = u * cw, ua * cwa
            out = (u, ua)
        self._memo[tree] = out
        return out

    def _into(self, colour: str, child: tuple):
        """``M u(child)``: a child's stage vector carried into a parent's stages (memoised)."""
        key = (colour, child)
        if key in self._carried:
            return self._carried[key]
        matrix = self.coupling[(colour, child[0])]
        if self.exact:
            cu = self._stage(child)
            zero = self.arith.zero
            out = [sum((m * cu[j] for j, m in row), zero) for row in matrix]
        else:
            cu, cua = self._stage(child)
            out = (matrix @ cu, self.abs_coupling[(colour, child[0])] @ cua)
        self._carried[key] = out
        return out

    def holds(self, tree: tuple, order: int, gamma: int) -> bool:
        """Whether ``Phi(t) = 1/gamma`` for the coloured tree with ``order`` vertices."""
        colour = tree[0]
        target = self.arith.rational(1, gamma)
        if self.exact:
            u = self._stage(tree)
            phi = sum((w * ui for w, ui in zip(self.weights[colour], u, strict=True)), self.arith.zero)
            return self.arith.satisfied(phi, target, 0.0, 0)
        u, ua = self._stage(tree)
        phi = float(self.weights[colour] @ u)
        scale = float(self.abs_weights[colour] @ ua)
        n_stages = len(self.weights[colour])
        return self.arith.satisfied(phi, target, scale, order * (n_stages + 1))


def _coloured(tree: tuple) -> tuple:
    """Recolour a plain tree as a one-colour tree ``("y", children)``."""
    return ("y", tuple(_coloured(child) for child in tree))


def _first_failure(weights: _Weights, families: Sequence[Callable[[int], tuple]], max_order: int) -> int:
    for p in range(1, max_order + 2):
        for family in families:
            for tree in family(p):
                if not weights.holds(tree, p, density(plain(tree))):
                    return p - 1
    raise OrderAboveLimit(max_order)


def rk_order(A: Sequence[Sequence], b: Sequence, max_order: int = 8) -> int:
    """Order of the Runge-Kutta method with tableau ``A`` (s x s, any structure), ``b``.

    Raises
    ------
    OrderAboveLimit
        All conditions through order ``max_order + 1`` hold.
    """
    s = len(b)
    rows = [list(row) for row in A]
    if len(rows) != s or any(len(row) != s for row in rows):
        raise ValueError(f"Butcher tableau: A must be {s} x {s} for {s} weights b")
    arith = Arithmetic([*(a for row in rows for a in row), *b])
    values = arith.elements()
    a_conv = [values[i * s:(i + 1) * s] for i in range(s)]
    weights = _Weights(arith, {"y": values[s * s:]}, {("y", "y"): a_conv})
    return _first_failure(weights, [lambda p: tuple(_coloured(t) for t in trees(p))], max_order)


def splitting_order(drift: Sequence, kick: Sequence, max_order: int = 8) -> int:
    """Order of the drift-first splitting on ``x' = v, v' = a(x)``.

    Raises
    ------
    OrderAboveLimit
        All conditions through order ``max_order + 1`` hold.
    """
    k = len(kick)
    if len(drift) != k + 1:
        raise ValueError(f"splitting: {len(drift)} drift and {k} kick coefficients; "
                         "drift first and last needs one drift more than kicks")
    arith = Arithmetic([*drift, *kick])
    values = arith.elements()
    a, b = values[: k + 1], values[k + 1:]
    zero = arith.zero
    kicks_before = [[b[j] if j < i else zero for j in range(k)] for i in range(k + 1)]   # drift i <- kick j
    drifts_before = [[a[i] if i <= j else zero for i in range(k + 1)] for j in range(k)]  # kick j <- drift i
    weights = _Weights(arith, {"x": a, "v": b}, {("x", "v"): kicks_before, ("v", "x"): drifts_before})
    families = [lambda p: nystrom_trees(p, "x"), lambda p: nystrom_trees(p, "v")]
    return _first_failure(weights, families, max_order)


__all__ = ["OrderAboveLimit", "rk_order", "size", "splitting_order"]
