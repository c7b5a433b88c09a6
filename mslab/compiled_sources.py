"""What compiled code runs: the source files in the cache key of every function mslab compiles.

:func:`sources_digest` is part of numba's cache key for each function :func:`mslab.jit.compiled`
makes (``mslab.jit._quick_cache_class``). Numba alone keys its cache by a function's own bytecode
and drops it when the function's own file changes, never when a callee's file does.
``tests/test_compiled_cache.py`` holds it (an edited helper module, an edit while a process runs).
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
import sys
import time
import types
import uuid
from collections.abc import Callable
from typing import Any

#: when this process loaded mslab's compiling code (a file edited later may not be what it runs)
_STARTED = time.time()
#: a cache key of this process alone
_THIS_PROCESS = f"this-process-{os.getpid()}-{uuid.uuid4().hex}"
_HERE = os.path.dirname(os.path.abspath(__file__))
#: the files that set the compile options
_OPTIONS = (os.path.join(_HERE, "jit.py"), os.path.join(_HERE, "fast", "compose.py"))


def sources_digest(function: Callable) -> str:
    """Return a hash of the source files of the mslab modules whose code ``function`` runs.

    Numba keys its cache by the function's own bytecode and drops it when the function's own
    file changes, never when a callee's does: an edited helper in another module (``mslab.lanes``
    under ``lane_sum``, the spring kernel under a generated loop) left the old machine code in
    use. Part of the cache key of every function :func:`mslab.jit.compiled` makes:
    the modules of the function and of every mslab function it names, transitively (through
    globals, modules named as globals, closures and nested code; compiled twins followed to their
    Python source; generated modules ``mslab_fast_*`` too), and the two files that set the compile
    options (``jit.py`` and ``fast/compose.py``). A file edited after this process started may differ
    from the code it imported: it gets a key of this process alone (compiled here, never reused
    by another process), as does anything the walk cannot read. Never raises.
    """
    try:
        modules = _modules_run_by(function)
        files = sorted({_source_file(name) for name in modules} | set(_OPTIONS))
        return "-".join(_file_digest(path) for path in files)
    except Exception:  # noqa: BLE001 (a key that cannot be formed must not stop a compile)
        return _THIS_PROCESS


def _modules_run_by(function: Callable) -> set[str]:
    """Return the names of the mslab modules whose functions ``function`` reaches (:func:`sources_digest`)."""
    modules: set[str] = set()
    seen: set[int] = set()
    todo: list[Any] = [function]
    while todo:
        fn = _python_function(todo.pop())
        if id(fn) in seen or not inspect.isfunction(fn):
            continue
        seen.add(id(fn))
        modules.add(str(fn.__module__))
        named = [cell.cell_contents for cell in fn.__closure__ or () if _filled(cell)]
        codes = [fn.__code__]
        while codes:  # the names of nested code (inner functions, comprehensions) too
            code = codes.pop()
            codes += [c for c in code.co_consts if isinstance(c, types.CodeType)]
            named += [fn.__globals__.get(name) for name in code.co_names]
        for value in map(_python_function, named):
            if inspect.ismodule(value) and value.__name__.startswith("mslab"):
                modules.add(value.__name__)
            elif inspect.isfunction(value) and str(value.__module__).startswith("mslab"):
                todo.append(value)
    return modules


def _python_function(value: Any) -> Any:
    """Return a numba dispatcher's Python function (``py_func``), else ``value`` itself."""
    try:
        return getattr(value, "py_func", value)
    except Exception:  # noqa: BLE001 (a lazy object whose attribute lookup fails: not a dispatcher)
        return value


def _filled(cell: Any) -> bool:
    try:
        cell.cell_contents  # noqa: B018
        return True
    except ValueError:  # an empty cell
        return False


def _source_file(module: str) -> str:
    """Return the source file of the imported ``module`` ("" without one)."""
    path = getattr(sys.modules.get(module), "__file__", None)
    return path if isinstance(path, str) else ""


@functools.cache
def _file_digest(path: str) -> str:
    """Return the sha256 of the file ``path``: "" without one, :data:`_THIS_PROCESS` if edited meanwhile.

    Edited meanwhile: a file of the mslab package modified after :data:`_STARTED` and before now
    (a time in the future is a skewed clock, not an edit, and is trusted).
    """
    if not path:
        return ""
    try:
        if not os.path.isfile(path):
            return ""
        if path.startswith(_HERE + os.sep) and _STARTED < os.stat(path).st_mtime <= time.time():
            return _THIS_PROCESS  # (a generated module is named by its text's hash: never edited)
        with open(path, "rb") as source:
            return hashlib.sha256(source.read()).hexdigest()[:16]
    except OSError:
        return ""
