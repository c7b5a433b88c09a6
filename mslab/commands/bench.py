"""``mslab bench``: how fast mslab is, as ratios to references timed in the same run.

Decision: the harnesses and their reference kernels live in the repository's ``benchmarks/``
folder, not in the package; this command runs them from a checkout (it finds the folder
next to the ``mslab`` package) and says in one line that it needs a checkout when mslab is
installed without it (from a wheel). Prints the targets of the compiled fast path and whether
each one is met;
``--quick`` (about half a minute) uses fewer steps and repeats and builds the 300 x 300
cloth's springs directly instead of through the SceneBuilder. ``--out DIR`` also writes
``bench.json`` and ``bench.md`` (the table). Exit code 0 whether or not the targets are
met: timings are measurements, not tests.
"""

from __future__ import annotations

import json
import sys
from typing import TYPE_CHECKING

from mslab.commands.common import CommandError, add_common_options, atomic_write, emit_json, out_dir, say

if TYPE_CHECKING:
    import argparse
    from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab bench`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "bench",
        help="speed of the compiled path as ratios to reference kernels",
        description="Time mslab against references written in the benchmark (numba loops, "
                    "scipy solve_ivp) and print the ratios and whether each target is met.",
    )
    p.add_argument("--quick", action="store_true", help="fewer steps and repeats (about 30 s)")
    add_common_options(p)
    p.set_defaults(func=run)


def _suite():
    """``benchmarks.suite`` of the checkout this mslab runs from (CommandError in one line without one).

    The checkout is the folder holding both the running ``mslab`` package and
    ``benchmarks/``. Its ``benchmarks`` package is loaded from its files; ``sys.path`` is
    left as it is, so nothing else of the checkout can shadow an installed module.
    """
    import importlib
    import importlib.util
    from pathlib import Path

    package = Path(__file__).resolve().parents[1]
    root = package.parent
    folder = root / "benchmarks"
    if not (folder / "suite.py").is_file() or not (folder / "__init__.py").is_file():
        raise CommandError(f"needs a checkout of the repository (its benchmarks/ folder); this mslab is "
                           f"installed at {package} without it: run it from a git clone", where="bench")
    if "benchmarks" not in sys.modules:
        spec = importlib.util.spec_from_file_location("benchmarks", folder / "__init__.py",
                                                      submodule_search_locations=[str(folder)])
        module = importlib.util.module_from_spec(spec)
        sys.modules["benchmarks"] = module
        spec.loader.exec_module(module)
    return importlib.import_module("benchmarks.suite")


def run(args: argparse.Namespace) -> int:
    """Run ``mslab bench`` with the parsed ``args``; return the exit code."""
    benchmarks = _suite()

    def progress(name: str) -> None:
        if sys.stderr.isatty() or not args.json:
            say(args, f"  measuring {name} ...")

    doc = benchmarks.run_all(quick=args.quick, progress=progress)
    folder = out_dir(args)
    if folder is not None:
        atomic_write(folder / "bench.json", lambda p: _write(p, json.dumps(_plain(doc), indent=2)))
        atomic_write(folder / "bench.md", lambda p: _write(p, benchmarks.table(doc) + "\n"))
    if args.json:
        emit_json(doc)
        return 0
    m = doc["machine"]
    say(args, f"mslab bench{' --quick' if args.quick else ''}: {m['cpu']}, {m['cores']} cores, "
              f"numpy {m['numpy']}, numba {m['numba']}, scipy {m['scipy']}, {m['date']}")
    say(args, benchmarks.table(doc))
    met = sum(t["met"] for t in doc["targets"])
    say(args, f"{met} of {len(doc['targets'])} targets met (medians of repeats; a loaded machine "
              f"moves the ratios)")
    return 0


def _plain(doc: dict) -> dict:
    from mslab.commands.common import to_jsonable

    return to_jsonable(doc)


def _write(path: str | Path, text: str) -> None:
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
