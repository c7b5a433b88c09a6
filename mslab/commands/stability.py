"""``mslab stability METHOD...``: stability regions and limits of integrators.

For each method (``all`` or none given: every registered method) the table lists the left
end ``a`` of the real stability interval ``[a, 0]``, the imaginary limit (largest ``y``
with ``|R(iy)| <= 1``) and the oscillator limit (largest stable ``dt w`` on
``x'' = -w^2 x``), all computed from :mod:`mslab.stability`. ``--out DIR`` writes
``stability_regions.png`` (regions in the ``dt lam`` plane and spectral radius against
``dt w``) and ``stability.json``.
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING

from mslab.commands.common import (
    CommandError,
    add_common_options,
    atomic_write,
    emit_json,
    out_dir,
    say,
    to_jsonable,
)
from mslab.integrators.base import get_method

if TYPE_CHECKING:
    import argparse
    from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab stability`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "stability", help="stability regions, real/imaginary intervals and oscillator limits of methods",
        description="Dahlquist stability (R(z), z = dt*lambda) and the oscillator test of each method.")
    p.add_argument("methods", nargs="*", metavar="METHOD", help="method names, or 'all' (default: all)")
    add_common_options(p)
    p.set_defaults(func=run)


def _methods(names: list[str]) -> list[str]:
    from mslab.integrators.base import get_method, methods

    if not names or "all" in names:
        return methods()
    out = []
    for name in names:
        try:
            out.append(get_method(name).name)
        except ValueError as err:
            raise CommandError(str(err), key="METHOD") from None
    return out


def _fmt(value: float) -> str:
    if math.isinf(value):
        return "-inf" if value < 0 else "inf"
    return f"{value:.4f}"


def run(args: argparse.Namespace) -> int:
    """Run ``mslab stability`` with the parsed ``args``; return the exit code."""
    from mslab.stability import summary

    names = _methods(args.methods)
    rows = summary(names)
    folder = out_dir(args)
    figures = []
    if folder is not None:
        figures.append(str(_figure(names, folder)))
    doc = {"methods": rows, "figures": figures,
           "notes": "infinite limits are written as null in JSON (-inf real interval: A-stable)"}
    if folder is not None:
        atomic_write(folder / "stability.json",
                     lambda tmp: open(tmp, "w").write(json.dumps(to_jsonable(doc), indent=2) + "\n"))
    if args.json:
        emit_json(doc)
        return 0
    header = ["method", "explicit", "order", "real interval [a, 0]", "imag limit", "oscillator h*w"]
    lines = [[r["method"], "yes" if r["explicit"] else "no", str(r["order"]), _fmt(r["real_interval"]),
              _fmt(r["imag_limit"]), _fmt(r["oscillator_limit"])] for r in rows]
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(header)]
    say(args, "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip())
    for line in lines:
        say(args, "  ".join(c.ljust(w) for c, w in zip(line, widths, strict=True)).rstrip())
    if any(get_method(r["method"]).symplectic and get_method(r["method"]).explicit for r in rows):
        say(args, "note: for the partitioned methods (symplectic Euler, Verlet, leapfrog) the real "
                  "interval is measured on a critically damped oscillator, not on y' = lam y: "
                  "see docs/stability.md")
    if any(r["method"] == "implicit_euler_fp" for r in rows):
        say(args, "note: implicit_euler_fp has R(z) of implicit Euler only while its fixed-point "
                  "iteration converges (h L < 1)")
    for f in figures:
        say(args, f"wrote {f}")
    return 0


def _figure(names: list[str], folder: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mslab.commands.common import save_figure
    from mslab.plots.stability import plot_oscillator_stability, plot_stability_regions

    fig, (left, right) = plt.subplots(1, 2, figsize=(15, 5.5))
    plot_stability_regions(names, ax=left)
    plot_oscillator_stability(names, ax=right)
    fig.tight_layout()
    return save_figure(fig, folder / "stability_regions.png")
