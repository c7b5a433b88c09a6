"""The Effect protocol and helpers shared by all force terms.

An *effect* is one force term of Newton's second law (seed eq. 3). It owns

* ``force(x, v)`` — the force on every particle, shape ``(n_particles, dim)``;
* ``energy(x)`` — its potential energy when it is conservative (else 0);
* ``power(x, v)`` — the power it dissipates (>= 0) when it is dissipative (else 0);
* ``jacobians(x, v)`` — ``(df/dx, df/dv)`` as ``scipy.sparse`` matrices of shape
  ``(n*dim, n*dim)`` (``None`` for a block that is identically zero), used by the
  implicit methods and by the stability analysis.

The flags ``velocity_dependent`` and ``dissipative`` let the :class:`~mslab.system.System`
skip work that no effect of the scene asks for.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class Effect:
    """Base class of a force term. Subclasses set the class flags and the methods."""

    name: str = "effect"
    velocity_dependent: bool = False
    dissipative: bool = False
    conservative: bool = True

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def force_and_power(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Force and dissipated power from one pass (default: two calls)."""
        f = self.force(x, v)
        return f, (self.power(x, v) if self.dissipative else 0.0)

    def energy(self, x: np.ndarray) -> float:
        return 0.0

    def power(self, x: np.ndarray, v: np.ndarray) -> float:
        return 0.0

    def jacobians(self, x: np.ndarray, v: np.ndarray):
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def block_diagonal(blocks: np.ndarray, particles: np.ndarray, n: int) -> sp.csr_matrix:
    """Sparse ``(n*dim, n*dim)`` matrix with ``blocks[k]`` at particle ``particles[k]``.

    ``blocks`` has shape ``(m, dim, dim)``; repeated particles are summed.
    """
    m, dim, _ = blocks.shape
    rows = (particles[:, None] * dim + np.arange(dim)[None, :])  # (m, dim)
    r = np.repeat(rows, dim, axis=1).ravel()
    c = np.tile(rows, (1, dim)).ravel()
    return sp.csr_matrix((blocks.ravel(), (r, c)), shape=(n * dim, n * dim))


def pair_blocks(blocks: np.ndarray, i: np.ndarray, j: np.ndarray, n: int) -> sp.csr_matrix:
    """Sparse matrix of pair interactions: ``+B`` at (i,i), (j,j) and ``-B`` at (i,j), (j,i).

    This is the pattern of any force that depends on ``x_i - x_j`` only (a spring):
    with ``B = df_i/dx_i`` we have ``df_i/dx_j = -B``, ``df_j/dx_j = B``, ``df_j/dx_i = -B``.
    """
    m, dim, _ = blocks.shape
    ri = i[:, None] * dim + np.arange(dim)[None, :]
    rj = j[:, None] * dim + np.arange(dim)[None, :]

    def grid(a, b):
        return np.repeat(a, dim, axis=1).ravel(), np.tile(b, (1, dim)).ravel()

    parts = [(grid(ri, ri), blocks), (grid(rj, rj), blocks),
             (grid(ri, rj), -blocks), (grid(rj, ri), -blocks)]
    r = np.concatenate([p[0][0] for p in parts])
    c = np.concatenate([p[0][1] for p in parts])
    d = np.concatenate([p[1].ravel() for p in parts])
    return sp.csr_matrix((d, (r, c)), shape=(n * dim, n * dim))
