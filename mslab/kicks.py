"""The kick pass of the compiled splitting loops, in numba-compatible style: one definition.

The stepping loops (:mod:`mslab.fast.loops`) call it over the parts of the particles; the
springs' kernel twin :func:`mslab.effects.spring_kick.spring_kernel_kick` calls it block by
block, as soon as a block's forces are complete. Either way each entry gets the same
operations, so the results are bitwise the same.
"""

from __future__ import annotations

import numpy as np


def kick(xf: np.ndarray, vf: np.ndarray, ff: np.ndarray, f0f: np.ndarray, w: np.ndarray, h: float,
         hd: float, limit: float) -> int:
    """Do ``a = w f; f = f0; v += h a; x += hd v`` in one pass; return the count of bad entries.

    Flat entries (coordinate-major: :mod:`mslab.fast.loops`): ``w`` the inverse masses tiled
    per coordinate, ``f0`` the constant forces the next force evaluation starts from, ``h``
    the kick's and ``hd`` the drift's step. An entry is bad where ``|x| >= limit`` or ``v``
    is not finite (the blow-up test). Cost ``O(entries)``, branch-free: numba vectorises it.
    """
    count = 0
    for e in range(xf.size):
        aq = w[e] * ff[e]
        ff[e] = f0f[e]
        vq = vf[e] + h * aq
        vf[e] = vq
        xq = xf[e] + hd * vq
        xf[e] = xq
        count += 0 if (abs(xq) < limit and vq - vq == 0.0) else 1
    return count
