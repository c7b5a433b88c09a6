"""Plain functions of the effects compiled by numba on first use (cached on disk)."""

from __future__ import annotations

from collections.abc import Callable

_COMPILED: dict[Callable, Callable] = {}


def compiled(function: Callable) -> Callable:
    """Return ``numba.njit(cache=True)(function)``, compiled once per process (numba caches it on disk)."""
    fast = _COMPILED.get(function)
    if fast is None:
        import numba

        fast = _COMPILED[function] = numba.njit(cache=True)(function)
    return fast
