"""What every subcommand shares: clear errors, JSON output, output folders, atomic writes, scenes, tables."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mslab.files import atomic_write  # noqa: F401  (the commands import it from here)

if TYPE_CHECKING:
    from collections.abc import Sequence

    from matplotlib.figure import Figure

    from mslab.scene import Scene


class CommandError(Exception):
    """A user mistake: printed as one line ``mslab: error: WHERE: KEY: reason``, exit 2."""

    def __init__(self, reason: str, where: str | None = None, key: str | None = None):
        parts = [p for p in (where, key, reason) if p]
        super().__init__(": ".join(parts))


def add_common_options(parser: argparse.ArgumentParser, out: bool = True) -> None:
    """Add ``--json`` (one JSON document on stdout) and ``--out DIR``."""
    parser.add_argument("--json", action="store_true", help="print one JSON document on stdout, nothing else")
    if out:
        parser.add_argument("--out", metavar="DIR", default=None, help="folder for figures and data")


def to_jsonable(obj: Any) -> Any:
    """Convert numpy scalars/arrays (and nested containers) for json.dumps."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating | float):
        value = float(obj)
        return value if np.isfinite(value) else None
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def emit_json(doc: dict) -> None:
    """Write exactly one JSON document to stdout."""
    sys.stdout.write(json.dumps(to_jsonable(doc), indent=2) + "\n")
    sys.stdout.flush()


def say(args: argparse.Namespace, text: str) -> None:
    """Print human-readable output: stdout normally, stderr when --json owns stdout."""
    print(text, file=sys.stderr if getattr(args, "json", False) else sys.stdout)


def out_dir(args: argparse.Namespace, default: str | None = None) -> Path | None:
    """Return the --out folder (created), or None when no figures/data were asked for."""
    folder = getattr(args, "out", None) or default
    if folder is None:
        return None
    path = Path(folder)
    path.mkdir(parents=True, exist_ok=True)
    return path


def out_path(args: argparse.Namespace, default: str | None = None) -> Path | None:
    """Return the --out folder, not created yet (files create it as they are written), or None.

    A run interrupted before it wrote anything leaves no empty folder behind.
    """
    folder = getattr(args, "out", None) or default
    return None if folder is None else Path(folder)


def add_budget_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--max-memory SIZE``, the memory budget of a run's saved data."""
    parser.add_argument("--max-memory", dest="max_memory", metavar="SIZE", default=None,
                        help="refuse a run whose saved data exceed SIZE (e.g. 2G, 500M; "
                             "default: half the available memory)")


def memory_budget(args: argparse.Namespace) -> tuple[int | None, str]:
    """Return the budget in bytes from ``--max-memory`` (or the default) and where it comes from."""
    from mslab.budget import DEFAULT_FRACTION, default_budget, parse_size

    given = getattr(args, "max_memory", None)
    if given is not None:
        try:
            return parse_size(given), "--max-memory"
        except ValueError as err:
            raise CommandError(str(err), key="--max-memory") from None
    return default_budget(), f"{DEFAULT_FRACTION:.0%} of the available memory; --max-memory to change"


def method_help(what: str = "integrator") -> str:
    """Return the ``--method`` help text listing the registered methods."""
    from mslab.integrators.base import methods

    return f"{what}: {', '.join(methods())} (details: `mslab methods`)"


def number(maximum: float | None = None, **limits: Any) -> Callable[[str], float]:
    """Return an argparse ``type=`` reading a real number through :func:`mslab.checks.real`.

    ``limits``: ``positive``, ``minimum``, ``allow_inf`` as there; NaN, an infinity and a word
    that is no number are refused, and so is a number above ``maximum``. Command-line numbers
    pass the same checks as the API's arguments, and a refusal is argparse's one line
    ``mslab: error: --OPTION: reason``.
    """
    from mslab.checks import real

    return _option(float, lambda value: _at_most(real("", value, **limits), maximum), "number")


def count(minimum: int = 1, maximum: int | None = None) -> Callable[[str], int]:
    """Return an argparse ``type=`` reading a whole number ``>= minimum`` (and ``<= maximum``).

    Read through :func:`mslab.checks.whole`: ``1.5`` or ``1e3`` is refused, not rounded.
    """
    from mslab.checks import whole

    return _option(int, lambda value: _at_most(whole("", value, minimum), maximum), "whole number")


def _at_most(value: Any, maximum: float | None) -> Any:
    if maximum is not None and value > maximum:
        raise ValueError(f"must be <= {maximum:g}, got {value:g}")
    return value


def _option(parse: Callable[[str], Any], check: Callable[[Any], Any], what: str) -> Callable[[str], Any]:
    from mslab.checks import shown

    def read(word: str) -> Any:
        try:
            if "_" in word:  # Python's 1_000: no number a user types on a command line
                raise ValueError(word)
            value = parse(word)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a {what}, got {shown(word)}") from None
        try:
            return check(value)
        except (TypeError, ValueError) as err:  # the checks' message, less the (empty) argument name
            raise argparse.ArgumentTypeError(str(err).strip()) from None

    read.__name__ = what
    return read


def add_settings_options(p: argparse.ArgumentParser) -> None:
    """Add ``--method --dt --t-end --save-every``, which override the scene file's [run] settings."""
    p.add_argument("--method", default=None, metavar="METHOD", help=method_help())
    p.add_argument("--dt", type=number(positive=True), default=None, help="time step [s]")
    p.add_argument("--t-end", dest="t_end", type=number(positive=True), default=None, help="end time [s]")
    p.add_argument("--save-every", dest="save_every", type=count(1), default=None,
                   help="keep every n-th step")


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Save a matplotlib figure atomically (PNG, fixed dpi) and close it."""
    import matplotlib.pyplot as plt

    result = atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=110, format=Path(path).suffix[1:] or "png"))
    plt.close(fig)
    return result


def write_json(path: str | Path, doc: dict) -> Path:
    """Write ``doc`` as JSON to ``path`` atomically."""
    text = json.dumps(to_jsonable(doc), indent=2) + "\n"

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    return atomic_write(path, write)


#: scenes generated in code when no scene file of that name exists
GENERATED = ("chain", "oscillator")


def resolve_scene(spec: str, **overrides) -> Scene:
    """Return a scene by name or path through ``mslab.load_scene``; generator names as fallback.

    ``oscillator`` (and ``chain`` while no scene file is installed) come from
    :mod:`mslab.scenes.generators`. ``overrides`` (dt, t_end, ...) replace run settings.
    """
    from mslab.errors import SceneError
    from mslab.scenes.loader import load_scene

    given = {k: v for k, v in overrides.items() if v is not None}
    try:
        return load_scene(spec, **given)
    except SceneError:
        if spec not in GENERATED:
            raise
    if spec not in GENERATED:
        raise CommandError(f"unknown scene '{spec}'; valid here: {', '.join(GENERATED)}", key="SCENE")
    from mslab.scenes import generators

    scene = getattr(generators, spec)()
    return scene.with_settings(**given) if given else scene


def course_methods() -> list[str]:
    """Return the registered methods of the course, in the course's order."""
    from mslab.integrators.base import COURSE_METHODS, methods

    known = set(methods())
    return [m for m in COURSE_METHODS if m in known]


def method_list(names: Sequence[str] | None) -> list[str]:
    """Return the registry names of the methods asked for (``-`` or ``_``); course methods by default."""
    from mslab.integrators.base import get_method

    if not names:
        return course_methods()
    return [get_method(n).name for n in names]


def fmt(value: Any, spec: str = ".3g") -> str:
    """Format a table cell: ``-`` for None, ``inf``/``nan`` spelled out, floats with ``spec``."""
    if value is None:
        return "-"
    if isinstance(value, float) and not math.isfinite(value):
        return "inf" if value > 0 else ("nan" if math.isnan(value) else "-inf")
    return format(value, spec) if isinstance(value, float) else str(value)


def table(rows: list[list[str]], header: list[str]) -> str:
    """Plain fixed-width table; first column left-aligned, the others right-aligned."""
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]

    def line(r: list):
        return "  ".join(str(c).ljust(w) if i == 0 else str(c).rjust(w)
                         for i, (c, w) in enumerate(zip(r, widths, strict=True)))

    return "\n".join([line(header), "  ".join("-" * w for w in widths), *(line(r) for r in rows)])
