"""Compiled loops for one combination of effect kernels: a generated module, compiled by ``mslab.jit``.

Each effect with a compiled kernel defines it once, as a plain function in its own module
(``kernel(x, v, f, *params) -> power``, see :mod:`mslab.effects.base`). For a scene whose
effects all have kernels, :func:`module_for` writes a module that is the text of the
template :mod:`mslab.fast.loops` (plain functions) followed by::

    from mslab.effects.spring_kernels import spring_kernel as _py_k0  # source <hash>
    ...
    def scene_forces(x, v, f, params):
        power = 0.0
        power += _k0(x.T, v.T, f.T, *params[0])
        return power

and ``scene_forces_kick`` (the forces, then the splitting loop's kick pass; where the last
effect has a kick twin, ``Effect.kick_kernel``, that twin kicks each block of particles inside
its own parallel loop, one launch of the threads fewer: :mod:`mslab.effects.spring_kick`),
then imports it and replaces each of its functions by :func:`mslab.jit.compiled` of it
(:func:`compile_module`; the kernels ``_k0, _k1, ...`` too), so numba compiles the loops
with the kernels inlined, on first use, and caches them on disk: the one way mslab compiles.

Decision (measured, see ``benchmarks/RESULTS.md``): numba does not cache functions that take
other compiled functions as arguments (every process recompiled the loops: a cache miss
each time), so the composition is a generated source file. Its name is a hash of its whole
text, which includes a hash of each kernel's module (the kernel and the helpers it calls,
:func:`mslab.jit.compiled`): editing a kernel, a helper or the template
gives a new module and a fresh compile. A helper in another module (``mslab.lanes``) is in the
cache key of every compiled function that calls it (:func:`mslab.compiled_sources.sources_digest`): numba
alone would not notice an edited callee.
Files go to ``$MSLAB_CACHE_DIR`` or ``$XDG_CACHE_HOME/mslab`` (``~/.cache/mslab``), and
numba's cache to a ``__pycache__`` beside them (or ``$NUMBA_CACHE_DIR``).
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType

_MARKER = "# -- scene forces (generated) --"
#: the template's functions imported from other modules: compiled with its own
_HELPERS = ("_kick",)
_modules: dict[tuple, ModuleType] = {}


def cache_dir() -> Path:
    """Where generated modules are written (created on demand).

    ``$MSLAB_CACHE_DIR``, else ``$XDG_CACHE_HOME/mslab`` (``~/.cache/mslab``); where that
    cannot be created (a read-only home), a folder of this user in the temporary directory.
    OSError when neither can.
    """
    root = os.environ.get("MSLAB_CACHE_DIR")
    if not root:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(base, "mslab")
    try:
        path = Path(root) / "fast"
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        path = Path(tempfile.gettempdir()) / f"mslab-{os.getuid()}" / "fast"
        path.mkdir(parents=True, exist_ok=True)
    return path


def _template() -> str:
    path = Path(__file__).with_name("loops.py")
    text = path.read_text(encoding="utf-8")
    return text[: text.index(_MARKER)]


#: the particle pass of a module for scenes below ``MIN_ENTRIES_PARALLEL`` (one part): the
#: template's parallel version is replaced, so numba never compiles its parallel loop there
#: (6-8 s of a cold compile of the splitting loop, measured)
_ONE_PART = '''

def _particle_pass(code, xf, vf, ff, f0f, w, maf, h, hd, limit, cuts):
    """Do the pass ``code`` over all entries on the calling thread (a scene of one part)."""
    return _part(code, xf, vf, ff, f0f, w, maf, h, hd, limit)
'''


#: use the last kernel's kick twin (``Effect.kick_kernel``) where it has one (False: the forces
#: and the pass apart, as for every other scene; ``benchmarks/fused_kick.py`` compares them)
FUSED_KICK = True


def _import(kern: Callable, alias: str) -> str:
    body = inspect.getsource(sys.modules[kern.__module__])  # the kernel and its helpers
    digest = hashlib.sha256(body.encode()).hexdigest()[:16]
    return f"from {kern.__module__} import {kern.__name__} as _py_{alias}  # source {digest}"


def source(kernels: Sequence[Callable], parallel: bool = False, kick: Callable | None = None) -> str:
    """Return the generated module's text for these kernels, in summation order.

    ``parallel``: the particle passes may run in parts on all threads (a scene of
    :data:`mslab.fast.model.MIN_ENTRIES_PARALLEL` entries or more); else they are one part.
    ``kick``: the last kernel's twin that also kicks (:mod:`mslab.effects.spring_kick`), or
    None: ``scene_forces_kick`` is then ``scene_forces`` and the pass KICK.
    """
    lines = [_template().rstrip() + "\n", "" if parallel else _ONE_PART, "", f"{_MARKER}"]
    lines += [_import(kern, f"k{n}") for n, kern in enumerate(kernels)]
    if kick is not None:
        lines.append(_import(kick, "ktwin"))
    lines += ["", "", "def scene_forces(x, v, f, params):",
              '    """``f += sum_e f_e`` (arrays (dim, n); kernels get transposes); returns the power."""',
              "    power = 0.0"]
    lines += [f"    power += _k{n}(x.T, v.T, f.T, *params[{n}])" for n in range(len(kernels))]
    lines += ["    return power", "", "",
              "def scene_forces_kick(x, v, f, params, xf, vf, ff, f0f, w, maf, h, hd, limit, cuts, threads):",
              '    """The forces, then the pass KICK; returns the power and the count of bad entries."""']
    if kick is None:
        lines += ["    power = scene_forces(x, v, f, params)",
                  "    return power, _particle_pass(KICK, xf, vf, ff, f0f, w, maf, h, hd, limit, cuts)", ""]
        return "\n".join(lines)
    last = len(kernels) - 1
    lines += ["    power = 0.0"]
    lines += [f"    power += _k{n}(x.T, v.T, f.T, *params[{n}])" for n in range(last)]
    lines += ["    if threads > 1:  # (on one thread the pass apart measured faster)",
              f"        pw, bad = _ktwin(x.T, v.T, f.T, *params[{last}], xf, vf, ff, f0f, w, h, hd, limit)",
              "    else:",
              f"        pw, bad = _k{last}(x.T, v.T, f.T, *params[{last}]), -1",
              "    if bad < 0:  # the twin did not kick (its springs are one batch): the pass",
              "        bad = _particle_pass(KICK, xf, vf, ff, f0f, w, maf, h, hd, limit, cuts)",
              "    power += pw",
              "    return power, bad", ""]
    return "\n".join(lines)


#: what the announcement of a compilation calls the template's functions
WHAT = {"rhs": "the force loop", "run_explicit_rk": "the explicit Runge-Kutta loop",
        "run_splitting": "the splitting loop", "run_two_step": "the Verlet/leapfrog loop",
        "scene_forces": "the sum of the forces", "scene_forces_kick": "the forces and the kick"}


def compile_module(module: ModuleType, kernels: Sequence[Callable], kick: Callable | None = None) -> None:
    """Replace the functions of a generated module by :func:`~mslab.jit.compiled` of them.

    The template's functions get ``error_model="numpy"`` (no zero-division checks: numba
    vectorises the passes over particles); ``scene_forces`` and the kernels numba's defaults.
    Nothing compiles yet: each function compiles, or loads from the cache, on its first call.
    """
    from mslab.jit import compiled

    names = ", ".join(k.__name__.removesuffix("_kernel") for k in kernels) or "no"
    for n, kern in enumerate(kernels):
        setattr(module, f"_k{n}", compiled(kern, f"the {kern.__name__}"))
    if kick is not None:
        module._ktwin = compiled(kick, f"the {kick.__name__}")
    for name in _HELPERS:  # the template's helpers from other modules (mslab.kicks)
        value = getattr(module, name)
        setattr(module, name, compiled(value, f"{value.__name__}, a helper of the stepping loops",
                                       error_model="numpy"))
    own = [(name, value) for name, value in vars(module).items()
           if inspect.isfunction(value) and value.__module__ == module.__name__]
    # a function with a parallel loop is compiled from a copy of the module's globals
    # (mslab.jit._resolved): it comes last, when the functions it calls are compiled twins
    own.sort(key=lambda item: "prange" in item[1].__code__.co_names)
    for name, value in own:
        what = f"{WHAT.get(name, 'a helper of the stepping loops')} over the {names} kernels"
        options = {} if name.startswith("scene_forces") else {"error_model": "numpy"}
        setattr(module, name, compiled(value, what, helpers=False, **options))


def _key(kernels: Sequence[Callable], parallel: bool, kick: Callable | None = None) -> tuple:
    twin = None if kick is None else (kick.__module__, kick.__qualname__)
    return tuple((k.__module__, k.__qualname__) for k in kernels) + (parallel, twin)


def _path(text: str) -> tuple[str, Path]:
    name = "mslab_fast_" + hashlib.sha256(text.encode()).hexdigest()[:20]
    return name, cache_dir() / f"{name}.py"


def state(kernels: Sequence[Callable], parallel: bool = False, kick: Callable | None = None) -> str:
    """Return where the loops for these kernels come from.

    ``"loaded"`` (in this process), ``"cached"`` (generated before: numba loads it from its
    cache) or ``"new"`` (numba compiles it: seconds).
    """
    kick = kick if FUSED_KICK else None
    if _key(kernels, parallel, kick) in _modules:
        return "loaded"
    return "cached" if _path(source(kernels, parallel, kick))[1].exists() else "new"


def _write_once(path: Path, text: str) -> None:
    """Write ``path`` atomically, never replacing a complete copy another process wrote first.

    A new time stamp would void numba's cache of it.
    """
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        try:
            os.link(tmp, path)  # fails if the file exists: the first complete copy stays
        except FileExistsError:
            if path.read_text(encoding="utf-8") != text:  # a damaged copy: replace it
                os.replace(tmp, path)
        except OSError:  # no hard links on this file system
            os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def module_for(kernels: Sequence[Callable], parallel: bool = False,
               kick: Callable | None = None) -> ModuleType:
    """Return the compiled loops for these kernels (generated, written and imported once per process).

    ``parallel``: with the particle passes in parts on all threads; ``kick``: the last
    kernel's kick twin, used unless :data:`FUSED_KICK` is off (:func:`source`).
    """
    kick = kick if FUSED_KICK else None
    key = _key(kernels, parallel, kick)
    if key in _modules:
        return _modules[key]
    text = source(kernels, parallel, kick)
    name, path = _path(text)
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        _write_once(path, text)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    compile_module(module, kernels, kick)
    _modules[key] = module
    return module
