"""Rooted trees: the index set of the order conditions (Butcher series).

A tree is a tuple of its root's subtrees, sorted, so that every tree has exactly one
representation (``()`` is the single vertex, ``((),)`` the two-vertex chain). A
*Nyström tree* (for ``x' = v``, ``v' = a(x)``) carries colours that alternate along every
edge: a drift vertex (``x`` component, ``f = v``) has at most one child, a kick vertex
(``v`` component, ``g = a(x)``); every other elementary differential is zero for that
problem (``v`` is linear in ``v``, ``a`` does not depend on ``v``). It is a pair
``(colour, children)`` with colour ``"x"`` or ``"v"``.

References: J. C. Butcher, *Numerical Methods for Ordinary Differential Equations*, 3rd ed.
(Wiley 2016), ch. 3; E. Hairer, S. P. Nørsett, G. Wanner, *Solving Ordinary Differential
Equations I*, 2nd ed. (Springer 1993), sec. II.2 (trees) and II.14 (Nyström methods).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

Tree = tuple  # tuple of subtrees (plain) or (colour, tuple of subtrees) (Nyström)


@cache
def size(tree: Tree) -> int:
    """Return the number of vertices ``|t|`` of a plain tree."""
    return 1 + sum(size(child) for child in tree)


@cache
def density(tree: Tree) -> int:
    """Butcher's density ``gamma(t) = |t| * prod gamma(children)`` of a plain tree."""
    out = size(tree)
    for child in tree:
        out *= density(child)
    return out


def _forests(total: int, largest: tuple, trees_of: Callable[[int], tuple]) -> list[tuple]:
    """Multisets of trees with ``total`` vertices in all, each at most ``largest``.

    A multiset is a tuple sorted in decreasing ``(size, tree)`` order; ``largest`` is the
    ``(size, tree)`` key that bounds its first element (so each multiset comes once).
    """
    if total == 0:
        return [()]
    out = []
    for k in range(min(total, largest[0]), 0, -1):
        for tree in trees_of(k):
            key = (k, tree)
            if key > largest:
                continue
            out.extend((tree, *rest) for rest in _forests(total - k, key, trees_of))
    return out


@cache
def trees(order: int) -> tuple[Tree, ...]:
    """All rooted trees with ``order`` vertices (1, 1, 2, 4, 9, 20, 48, 115, 286, ...)."""
    if order < 1:
        return ()
    largest = (order, (float("inf"),))  # bigger than every real (size, tree) key
    return tuple(_forests(order - 1, largest, trees))


@cache
def nystrom_trees(order: int, colour: str) -> tuple[Tree, ...]:
    """Nyström trees with ``order`` vertices and a root of ``colour`` (``"x"`` or ``"v"``).

    An ``x`` vertex has no child or one ``v`` child; a ``v`` vertex has any number of
    ``x`` children.
    """
    if order < 1:
        return ()
    if colour == "x":
        if order == 1:
            return (("x", ()),)
        return tuple(("x", (child,)) for child in nystrom_trees(order - 1, "v"))
    largest = (order, ("~",))  # "~" sorts after "x": bigger than every real key
    return tuple(("v", forest) for forest in _forests(order - 1, largest, _x_trees))


def _x_trees(order: int) -> tuple[Tree, ...]:
    return nystrom_trees(order, "x")


@cache
def plain(tree: Tree) -> Tree:
    """Forget the colours of a Nyström tree (for ``|t|`` and ``gamma``)."""
    return tuple(sorted((plain(child) for child in tree[1]), key=lambda t: (size(t), t), reverse=True))
