"""Eight running sums in one vector register: the compiled core of ``lane_sum`` of the springs.

:func:`mslab.effects.spring_kernels.lane_sum` adds a run's dissipated powers in eight lanes
(value ``s`` into lane ``s % 8``, each lane in order, the lanes then added pairwise): an order
fixed by the code, so the sum is the same on every machine. Written as eight scalar
accumulators, numba's compiler keeps them scalar: a load, a conversion and an addition per
value, about 0.47 ns per float32 value (a fifth of a float32 spring's time in the compiled
loop). The compiler may not vectorise the sum itself (that would let it reorder the
additions), so this module hands it the vector form: :func:`eight_lanes` loads eight values at
a time and adds them to eight float64 lanes with one vector addition. Lane ``l`` still receives
``values[l], values[l + 8], ...`` in that order, each addition one IEEE-754 double addition, so
the sums are bitwise those of the scalar code on any machine (a CPU with narrower vectors
splits the addition, lane by lane). Measured 0.15-0.17 ns per float32 value, 0.07-0.13 per
float64 value (``benchmarks/RESULTS.md``).

Without numba :func:`eight_lanes` is the plain loop below; with numba, :func:`register` (called
by :func:`mslab.jit.numba` when numba is first loaded) gives it a compiled implementation
written in LLVM's vector instructions (numba's documented ``intrinsic`` and ``overload``
extension points).
"""

from __future__ import annotations

from typing import Any

import numpy as np


def eight_lanes(values: np.ndarray, stop: int) -> tuple[float, ...]:
    """Return the eight sums ``sum(values[l:stop:8])``, ``l = 0..7``, in float64, each in index order.

    ``stop`` is a multiple of 8, at most ``values.size``. Cost ``O(stop)``; compiled, one vector
    addition per eight values (C-contiguous float32 or float64 ``values``; others compile this
    scalar loop).
    """
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    for q in range(0, stop, 8):
        s0 += float(values[q])
        s1 += float(values[q + 1])
        s2 += float(values[q + 2])
        s3 += float(values[q + 3])
        s4 += float(values[q + 4])
        s5 += float(values[q + 5])
        s6 += float(values[q + 6])
        s7 += float(values[q + 7])
    return s0, s1, s2, s3, s4, s5, s6, s7


eight_lanes.mslab_overloaded = True  # mslab.jit leaves it to its overload (no compiled twin of the loop)


def register() -> None:
    """Give :func:`eight_lanes` its compiled implementation (once, when numba is loaded)."""
    import numba
    from llvmlite import ir
    from numba.core import cgutils, types
    from numba.extending import intrinsic, overload

    def supported(values: Any) -> bool:
        return (isinstance(values, types.Array) and values.ndim == 1 and values.layout == "C"
                and values.dtype in (types.float32, types.float64))

    scalar_lanes = numba.njit(eight_lanes)

    @intrinsic
    def vector_lanes(typingctx: Any, values: Any, stop: Any) -> Any:
        if not (supported(values) and isinstance(stop, types.Integer)):
            return None
        signature = types.UniTuple(types.float64, 8)(values, stop)

        def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            array = context.make_array(sig.args[0])(context, builder, args[0])
            item = context.get_data_type(sig.args[0].dtype)
            doubles = ir.VectorType(ir.DoubleType(), 8)
            lanes = cgutils.alloca_once_value(builder, ir.Constant(doubles, [0.0] * 8))
            intp = context.get_value_type(types.intp)
            stop_value = context.cast(builder, args[1], sig.args[1], types.intp)
            with cgutils.for_range_slice(builder, ir.Constant(intp, 0), stop_value, ir.Constant(intp, 8),
                                         intp) as (q, _):
                pointer = builder.bitcast(builder.gep(array.data, [q]), ir.VectorType(item, 8).as_pointer())
                eight = builder.load(pointer, align=4)
                if sig.args[0].dtype == types.float32:
                    eight = builder.fpext(eight, doubles)  # exact, as the scalar code's conversion
                builder.store(builder.fadd(builder.load(lanes), eight), lanes)
            total = builder.load(lanes)
            out = context.get_constant_undef(sig.return_type)
            for lane in range(8):
                value = builder.extract_element(total, ir.Constant(ir.IntType(32), lane))
                out = builder.insert_value(out, value, lane)
            return out

        return signature, codegen

    @overload(eight_lanes)
    def _eight_lanes(values, stop):  # noqa: ANN001, ANN202 (numba compares its signature, annotations too)
        if not isinstance(stop, types.Integer):
            return None
        if supported(values):
            return lambda values, stop: vector_lanes(values, stop)
        return lambda values, stop: scalar_lanes(values, stop)  # other arrays: the scalar loop


def state_sums(terms: np.ndarray) -> np.ndarray:
    """Return ``[np.sum(terms[s]) for s]``, bitwise: the sums of the ledger's energies of k states at once.

    A sum over an axis of the whole array pairs the additions differently from a sum of one
    state's terms, so each state keeps its own reduction (``np.add.reduce`` over its contiguous
    terms, what ``np.sum`` calls, without its Python wrapper: about 1.5 us a state, not 7).
    """
    return np.array([np.add.reduce(row, axis=None) for row in terms], dtype=float)
