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

import functools
import inspect
import os
import sys
import types
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from typing import Any

from mslab.compiled_sources import sources_digest
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


#: what running without numba costs, said once per process where ``auto`` would have compiled
MISSING = ("numba is not installed: backend 'auto' runs the numpy loops instead of the compiled ones "
           "(10-100x slower on scenes of thousands of springs; the same results to round-off); "
           "pip install numba to get them")


def available() -> bool:
    """Tell whether numba can be imported (once per process; no import of it before it is needed)."""
    if not _available:
        try:
            numba()
            _available.append(True)
        except ModuleNotFoundError:
            _available.append(False)
    return _available[0]


_available: list[bool] = []


def without_numba(backend: str) -> None:
    """Refuse ``backend="numba"`` without numba (one clear error); for ``"auto"`` say once what it costs.

    Called where the compiled loop was chosen; returns None (the numpy loop) for ``"auto"``.
    """
    import warnings

    from mslab.errors import PerformanceWarning

    if backend == "numba":
        raise ModuleNotFoundError("backend 'numba' needs numba, which is not installed: pip install numba, "
                                  "or use backend='numpy' (or 'auto', which falls back to it)", name="numba")
    if not _warned:
        _warned.append(True)
        warnings.warn(MISSING, PerformanceWarning, stacklevel=2)


_warned: list[bool] = []


def numba() -> Any:
    """Return the numba module, imported (protected from Ctrl-C) on first use.

    ModuleNotFoundError when numba is not installed (:func:`available` tells first).
    """
    if not _listening:
        # numba's OpenMP threads sleep between parallel loops instead of spinning (unless the
        # user chose): spinning threads made the spring loop 20-150x slower on a loaded 2-core
        # machine; they gain up to a third on an idle one (README, "Speed")
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
        with protected("loading numba"):
            import numba  # noqa: F401

            from mslab import lanes

            lanes.register()
            _listen()
            _listening.append(True)
    return sys.modules["numba"]


def prange(*args: int) -> range:
    """``range`` in Python; numba's ``prange`` (a loop split among threads) when compiled here.

    A compiled function that loops with it is compiled with ``parallel=True`` by
    :func:`compiled`; its iterations must not write to the same places (the caller's
    contract: e.g. conflict-free batches of springs).
    """
    return range(*args)


def _resolved(function: Callable, options: dict, helpers: bool) -> tuple[Callable, dict]:
    """Return ``function`` with the globals numba must see compiled, and its options.

    A plain function of mslab that ``function`` calls (a helper of a kernel, e.g.
    ``spring_range`` of ``spring_kernel``, or one imported from another kernel module)
    becomes its :func:`compiled` twin, and
    :func:`prange` becomes numba's (``parallel=True`` is then added to the options), in a
    copy of the function whose globals differ only there: the module itself is unchanged.
    A function marked ``mslab_overloaded`` keeps its numba overload (:mod:`mslab.lanes`).
    ``helpers=False`` leaves the helpers alone (a generated module whose functions are all
    replaced by their compiled twins: :func:`mslab.fast.compose.compile_module`).
    """
    names = function.__code__.co_names
    table = function.__globals__
    swaps: dict[str, Any] = {}
    for name in names:
        value = table.get(name)
        if value is prange:
            swaps[name] = numba().prange
            options = {**options, "parallel": True}
        elif (helpers and inspect.isfunction(value) and value is not function
              and value.__module__.split(".")[0] == "mslab"
              and not getattr(value, "mslab_overloaded", False)):
            helper_options = {k: v for k, v in options.items() if k != "parallel"}
            what = f"{value.__name__}, a helper of {function.__name__}"
            swaps[name] = compiled(value, what, **helper_options)
    if not swaps:
        return function, options
    copy = types.FunctionType(function.__code__, {**table, **swaps}, function.__name__,
                              function.__defaults__, function.__closure__)
    copy.__qualname__, copy.__module__ = function.__qualname__, function.__module__
    copy.__doc__ = function.__doc__
    return copy, options


def compiled(function: Callable, what: str | None = None, *, helpers: bool = True, **options: Any) -> Any:
    """Return ``function`` compiled by numba (``njit(cache=True, **options)``), once per process.

    Parameters
    ----------
    function : callable
        A plain module-level function in numba's subset of Python.
    what : str, optional
        What it is, for the announcement ("the springs' Jacobian loop"); default its name.
    helpers : bool
        Compile the plain functions of mslab that it calls along with it (default);
        a loop over :func:`prange` always becomes numba's parallel loop (:func:`_resolved`).
    **options
        Further ``njit`` options (``error_model="numpy"``).

    Returns
    -------
    numba dispatcher
        Called like ``function``; its first call with new argument types loads the compiled
        code from numba's cache or compiles it, protected from Ctrl-C.
    """
    key = (function, helpers, tuple(sorted(options.items())))
    fast = _COMPILED.get(key)
    if fast is None and not available():  # the plain Python function: the same code, slowly
        _COMPILED[key] = fast = function
    if fast is None:
        target, flags = _resolved(function, options, helpers)
        if flags.get("parallel"):
            # start numba's thread pool now: a caller loaded from the cache runs this code
            # without compiling it, and the pool would not be there (a crash, not an error)
            numba().get_num_threads()
        fast = numba().njit(cache=True, **flags)(target)
        _load_quickly(fast)
        fast.mslab_what = what or function.__name__
        original = fast.compile

        def compile(sig: Any, _original: Callable = original, _what: str = fast.mslab_what) -> Any:
            with protected(f"compiling {_what}"):
                return _original(sig)

        fast.compile = compile
        _COMPILED[key] = fast
    return fast


def _load_quickly(fast: Any) -> None:
    """Let the dispatcher ``fast`` load its cached code without numba's full target set-up.

    Before it loads a cached function numba imports and registers every implementation it
    could need to *compile* (``BaseContext.refresh``: its numpy, linear algebra and typed
    containers, with scipy's linear algebra; 0.4-0.8 s of a fresh process, measured in
    benchmarks/RESULTS.md, "A compiled loop that loads at once"). Machine code from the cache
    needs none of it, only numba's runtime (``rtsys``); a cache miss compiles as before
    (numba's compiler does the full set-up itself). Left as numba made it where numba lacks
    the internals this relies on.
    """
    cache = getattr(fast, "_cache", None)  # None: not a caching numba dispatcher
    needed = ("_load_overload", "_guard_against_spurious_io_errors")
    if cache is None or not all(hasattr(cache, n) for n in needed):
        return
    from numba.core import caching

    if not isinstance(cache, caching.FunctionCache):
        return
    cache.__class__ = _quick_cache_class()


@functools.cache
def _quick_cache_class() -> type:
    """Return numba's ``FunctionCache`` with a lean ``load_overload`` (made once per process)."""
    from numba.core import caching
    from numba.core.runtime import rtsys

    class QuickCache(caching.FunctionCache):
        def load_overload(self, sig: Any, target_context: Any) -> Any:
            rtsys.initialize(target_context)  # the runtime (allocation) the loaded code calls
            with self._guard_against_spurious_io_errors():
                return self._load_overload(sig, target_context)

        def _index_key(self, sig: Any, codegen: Any) -> Any:
            return (*super()._index_key(sig, codegen), sources_digest(self._py_func))

    return QuickCache


def thread_count(requested: int | None = None) -> int | None:
    """Return the threads compiled loops use: ``requested``, else ``$MSLAB_THREADS``, else None.

    None leaves numba's default: every core numba sees (``NUMBA_NUM_THREADS``). A number is
    clipped to 1..that many. Results never depend on it (the loops' batches are fixed by the
    scene: :mod:`mslab.effects.spring_batches`); only the speed does. ValueError for a count
    that is not a whole number >= 1.
    """
    if requested is None:
        text = os.environ.get("MSLAB_THREADS", "").strip()
        if not text:
            return None
        if not text.isdigit() or int(text) < 1:
            raise ValueError(f"MSLAB_THREADS: expected a whole number >= 1, got {text!r}")
        requested = int(text)
    if isinstance(requested, bool) or not isinstance(requested, int) or requested < 1:
        raise ValueError(f"threads: expected a whole number >= 1, got {requested!r}")
    return requested


@contextmanager
def threads(count: int | None) -> Iterator[None]:
    """Run the enclosed compiled calls on ``count`` threads (None: leave numba's setting)."""
    if count is None or not available():
        yield
        return
    nb = numba()
    previous = nb.get_num_threads()
    nb.set_num_threads(min(count, nb.config.NUMBA_NUM_THREADS))
    try:
        yield
    finally:
        nb.set_num_threads(previous)


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
