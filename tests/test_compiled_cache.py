"""Compiled code's disk cache follows the source it was compiled from (:mod:`mslab.compiled_sources`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.test_fast import _in_fresh_process


@pytest.mark.slow
def test_an_edited_helper_module_is_compiled_again(tmp_path):
    """Numba alone keeps a function's cached code when only a callee's file changes: mslab does not.

    A copy of mslab compiles ``lane_sum`` (its lanes are :mod:`mslab.lanes`, another module); after
    an edit of the copy's ``lanes.py`` that doubles every value added, a new process compiles
    again and returns twice the sum (numba's own key kept the stale machine code: 16.0). An edit
    while a process runs (after its import, before its compile) is compiled again by the next.
    """
    import shutil

    import mslab as original

    shutil.copytree(Path(original.__file__).parent, tmp_path / "copy" / "mslab",
                    ignore=shutil.ignore_patterns("__pycache__"))
    code = (f"import sys; sys.path.insert(0, {str(tmp_path / 'copy')!r}); "  # (before the working directory)
            "import numpy as np, mslab; from mslab.jit import compiled; "
            "from mslab.effects.spring_kernels import lane_sum; f = compiled(lane_sum); "
            f"assert mslab.__file__.startswith({str(tmp_path)!r}); "
            "print(f(np.ones(16)), sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values()))")
    env = {"MSLAB_CACHE_DIR": str(tmp_path / "gen"), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    assert _in_fresh_process(code, env) == "16.0 0 1"  # compiled
    assert _in_fresh_process(code, env) == "16.0 1 0"  # loaded
    lanes = tmp_path / "copy" / "mslab" / "lanes.py"
    text = lanes.read_text()
    add = "builder.fadd(builder.load(lanes), eight)"
    assert text.count(add) == 1  # (the vector addition of the lanes)
    doubled = text.replace(add, "builder.fadd(builder.fadd(builder.load(lanes), eight), eight)")
    lanes.write_text(doubled)
    assert _in_fresh_process(code, env) == "32.0 0 1"  # compiled again, the edit in force
    # an edit while a process runs: it compiles the code it imported (doubling), and must not file
    # it under the edited file's key, or the next process would load the doubling for the tripling
    tripled = doubled.replace("builder.fadd(builder.fadd(", "builder.fadd(builder.fadd(builder.fadd(")
    tripled = tripled.replace("eight), eight)", "eight), eight), eight)")
    edit = f"open({str(lanes)!r}, 'w').write({tripled!r}); "
    racing = code.replace("f = compiled(lane_sum); ", "f = compiled(lane_sum); " + edit)
    assert _in_fresh_process(racing, env) == "32.0 0 1"
    assert _in_fresh_process(code, env) == "48.0 0 1"


def test_the_walk_finds_helpers_by_closure_and_by_module_and_never_raises():
    """A closure over a kernel helper, a call through a module, odd globals: found, or a key all the same."""
    from mslab import lanes
    from mslab.compiled_sources import _modules_run_by, sources_digest
    from mslab.effects.spring_kernels import lane_sum

    def closure(values):
        return lane_sum(values)

    def through_module(values):
        return lanes.eight_lanes(values, 8)

    assert {"mslab.effects.spring_kernels", "mslab.lanes"} <= _modules_run_by(closure)
    assert "mslab.lanes" in _modules_run_by(through_module)

    class Lazy:  # a global whose attribute lookup fails with another error than AttributeError
        def __getattr__(self, name):
            raise ImportError(name)

    space = {"lane_sum": lane_sum, "lazy": Lazy()}
    exec("def nameless(values):\n    return lazy(lane_sum(values))", space)  # its __module__ is None
    key = sources_digest(space["nameless"])
    assert isinstance(key, str) and key == sources_digest(space["nameless"])
    assert sources_digest(len) == sources_digest(print)  # not Python functions: the options' files only
