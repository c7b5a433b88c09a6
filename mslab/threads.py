"""Single-threaded BLAS for mslab's small dense linear algebra.

Course-sized systems give small matrices (a few hundred unknowns): multi-threaded OpenBLAS
gains nothing there, and on a busy 2-core machine its threads made a 192x192 solve 20x
slower (7.6 ms against 0.4 ms) and a 300x300 one 30x slower. Newton's solves and the
eigenvalues of the step-limit prediction therefore run with one BLAS thread; the
caller's setting is restored afterwards.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TypeVar

F = TypeVar("F", bound=Callable)


def single_threaded_blas(func: F) -> F:
    """Wrap ``func`` to run with BLAS limited to one thread (threadpoolctl); a decorator."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
