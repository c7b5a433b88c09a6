"""The builder's cost grows with what is added, not with what is there already (issue 28).

Timing-free: the work of one builder call is counted at two scene sizes, 16 times apart
in particles and springs, as (a) the number of Python and C function calls it makes
(``sys.setprofile``; a loop over the scene's particles, springs or effect modules shows up
here) and (b) the memory it allocates transiently, median over the calls (``tracemalloc``;
a copy of the positions, ``np.array(list)``, shows up here although it is one call). An
O(1) call makes the same calls at both sizes and allocates the same few hundred bytes.
"""

from __future__ import annotations

import statistics
import sys
import tracemalloc
from collections.abc import Callable

import numpy as np
import pytest

import mslab
from mslab.scenes.generators import grid_springs

N_CALLS = 200


def _cloth_builder(side: int) -> mslab.SceneBuilder:
    """A 3D cloth of side**2 particles with its structural and bend springs (shear ones are left to add)."""
    b = mslab.SceneBuilder(dim=3)
    gx, gz = np.meshgrid(np.linspace(0.0, 1.0, side), np.linspace(-1.0, 0.0, side))
    b.add_particles(np.stack([gx.ravel(), np.zeros(side * side), gz.ravel()], axis=1))
    for kind in ("structural", "bend"):
        b.add_springs(grid_springs((side, side), kind), stiffness=100.0, kind=kind)
    return b


def _calls_made(fn: Callable[[], object]) -> int:
    count = 0

    def profile(frame, event, arg):
        nonlocal count
        if event in ("call", "c_call"):
            count += 1

    sys.setprofile(profile)
    try:
        fn()
    finally:
        sys.setprofile(None)
    return count


def _work(side: int, make_op: Callable[[mslab.SceneBuilder], Callable[[int], object]]) -> tuple[int, float]:
    """(function calls of N_CALLS ops, median bytes one op allocates transiently) on a cloth of ``side``.

    ``make_op(builder)`` prepares whatever the test needs (outside the counts) and returns
    ``op(k)``, the k-th call of the builder method under test.
    """
    b = _cloth_builder(side)
    op = make_op(b)
    for k in range(5):  # warm-up: first-call costs (imports, caches) are not per call
        op(k)
    calls = _calls_made(lambda: [op(k) for k in range(5, 5 + N_CALLS)])
    peaks = []
    tracemalloc.start()
    try:
        for k in range(5 + N_CALLS, 5 + 2 * N_CALLS):
            before = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            op(k)
            peaks.append(tracemalloc.get_traced_memory()[1] - before)
    finally:
        tracemalloc.stop()
    return calls, statistics.median(peaks)


def _with_pairs(kind: str, call: Callable[[mslab.SceneBuilder, int, int], object]):
    """An op adding a spring on the k-th ``kind`` pair of the cloth (pairs computed beforehand)."""
    def make(b: mslab.SceneBuilder) -> Callable[[int], object]:
        side = int(round(np.sqrt(b.n_particles)))
        pairs = grid_springs((side, side), kind).tolist()
        return lambda k: call(b, *pairs[k])
    return make


OPS = {
    "add_particle": lambda b: lambda k: b.add_particle([0.5, 1.0 + k, 0.0], mass=1.0),
    "add_spring": _with_pairs("shear", lambda b, i, j: b.add_spring(i, j, stiffness=50.0, kind="shear")),
    "add_springs of one pair": _with_pairs("shear", lambda b, i, j: b.add_springs([[i, j]], stiffness=50.0)),
    "add_spring, merged duplicate": _with_pairs("structural", lambda b, i, j: b.add_spring(
        j, i, stiffness=1.0, duplicates="merge")),
    "add_anchors": lambda b: lambda k: b.add_anchors([k], stiffness=10.0),
    "add_plane": lambda b: lambda k: b.add_plane([0.0, 1.0, 0.0], -1.0 - k, stiffness=1e3),
    "add_sphere": lambda b: lambda k: b.add_sphere([0.0, 0.0, float(k)], 0.1, stiffness=1e3),
}


@pytest.mark.parametrize("name", OPS)
def test_builder_call_cost_does_not_grow_with_the_scene(name):
    small, large = _work(24, OPS[name]), _work(96, OPS[name])
    print(name, small, large)
    # 16 times the particles and 16 times the springs: an O(1) call does the same work
    assert large[0] <= small[0] + N_CALLS // 20, (name, small, large)
    assert large[1] <= small[1] + 256, (name, small, large)


def test_add_spring_loop_builds_the_scene_of_add_springs():
    """The O(1) path of ``add_spring`` records what ``add_springs(pairs)`` records, bitwise."""
    side, rng = 7, np.random.default_rng(3)
    x = rng.normal(size=(side * side, 3))
    one, many = mslab.SceneBuilder(dim=3), mslab.SceneBuilder(dim=3)
    for p in x:
        one.add_particle(p, mass=2.0)
    many.add_particles(x, mass=2.0)
    for kind, k in (("structural", 500.0), ("shear", 50.0), ("bend", 5.0)):
        pairs = grid_springs((side, side), kind)
        for i, j in pairs.tolist():
            one.add_spring(i, j, stiffness=k, kind=kind, damping=0.5)
        many.add_springs(pairs, stiffness=k, kind=kind, damping=0.5)
    a, b = one.build(), many.build()
    sa, sb = a.springs(), b.springs()
    for name in ("springs", "stiffness", "rest_length", "damping", "kind"):
        np.testing.assert_array_equal(getattr(sa, name), getattr(sb, name))
    np.testing.assert_array_equal(a.state0.x, b.state0.x)
    # a duplicate after the fast path is still named with both springs
    named = r"spring \d+ \(\[1, 0\]\) joins the same two particles as spring 0"
    with pytest.raises(mslab.SceneError, match=named):
        one.add_spring(1, 0, stiffness=1.0)
