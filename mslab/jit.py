"""The one way mslab compiles: ``numba.njit(cache=True)``, announced, safe to interrupt.

Every compiled function of mslab comes from :func:`compiled`: the effects' kernels and
Jacobian loops, the local step of the fast mass-spring method, and the stepping loops of
:mod:`mslab.fast.loops` (which :mod:`mslab.fast.compose` writes into one generated module per
combination of kernels, then compiles here function by function). So all of them

* compile on first use and are cached on disk by numba (a later process loads them in a
  fraction of a second; a new machine, a fresh cache or an edited source compiles again);
* load or compile inside :func:`mslab.interrupts.protected`: a Ctrl-C then never lands
  inside numba (on the command line it ends the process with exit 130 and one line);
* announce a compilation (a cache miss, numba's ``numba:compile`` event) to the function set
  by :func:`announce_with`: the command line prints what is compiled, that it happens once
  and where it is cached, with a progress line by the clock on a terminal. A program or
  notebook sees nothing.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

from mslab.interrupts import protected

#: compiled functions of this process: (function, options) -> numba dispatcher
_COMPILED: dict[tuple, Any] = {}
#: ``announcer(what, where)``: a context manager around one compilation (None: silent)
_announcer: list[Callable[[str, str], AbstractContextManager] | None] = [None]
_listening: list[bool] = []


def announce_with(announcer: Callable[[str, str], AbstractContextManager] | None) -> Callable | None:
    """Set what a compilation shows (``announcer(what, where)``, a context manager; None: nothing).

    Returns the previous announcer (a command run inside another puts it back).
    """
    previous, _announcer[0] = _announcer[0], announcer
    return previous


def numba() -> Any:
    """Return the numba module, imported (protected from Ctrl-C) on first use."""
    if not _listening:
        with protected("loading numba"):
            import numba  # noqa: F401

            _listen()
            _listening.append(True)
    return sys.modules["numba"]


def compiled(function: Callable, what: str | None = None, **options: Any) -> Any:
    """Return ``function`` compiled by numba (``njit(cache=True, **options)``), once per process.

    Parameters
    ----------
    function : callable
        A plain module-level function in numba's subset of Python.
    what : str, optional
        What it is, for the announcement ("the springs' Jacobian loop"); default its name.
    **options
        Further ``njit`` options (``error_model="numpy"``).

    Returns
    -------
    numba dispatcher
        Called like ``function``; its first call with new argument types loads the compiled
        code from numba's cache or compiles it, protected from Ctrl-C.
    """
    key = (function, tuple(sorted(options.items())))
    fast = _COMPILED.get(key)
    if fast is None:
        fast = numba().njit(cache=True, **options)(function)
        fast.mslab_what = what or function.__name__
        original = fast.compile

        def compile(sig: Any, _original: Callable = original, _what: str = fast.mslab_what) -> Any:
            with protected(f"compiling {_what}"):
                return _original(sig)

        fast.compile = compile
        _COMPILED[key] = fast
    return fast


def cache_path(fast: Any) -> str:
    """Return the folder where numba caches the compiled code of the dispatcher ``fast``."""
    try:
        return str(fast._cache.cache_path)
    except AttributeError:  # a numba without this attribute: say where to look
        return "numba's cache (NUMBA_CACHE_DIR)"


class _Notices:
    """Announces the outermost compilation (a cache miss) through the announcer."""

    def __init__(self):
        self.depth = 0
        self.open: list[AbstractContextManager] = []

    def start(self, event: Any) -> None:
        self.depth += 1
        announcer = _announcer[0]
        if self.depth == 1 and announcer is not None:
            fast = event.data.get("dispatcher")
            what = getattr(fast, "mslab_what", None) or getattr(fast, "__name__", "numba code")
            notice = announcer(what, cache_path(fast))
            notice.__enter__()
            self.open.append(notice)

    def end(self, event: Any) -> None:
        self.depth -= 1
        if self.depth == 0 and self.open:
            self.open.pop().__exit__(None, None, None)


def _listen() -> None:
    """Register :class:`_Notices` for numba's ``numba:compile`` events (once per process)."""
    from numba.core import event

    notices = _Notices()

    class Listener(event.Listener):
        def on_start(self, ev: Any) -> None:
            notices.start(ev)

        def on_end(self, ev: Any) -> None:
            notices.end(ev)

    event.register("numba:compile", Listener())
