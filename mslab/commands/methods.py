"""``mslab methods``: the registered integrators with their order, stages and family.

One row per method of the registry (``mslab.methods()``: the course's first, in teaching
order): global order, force evaluations per step (per iteration for implicit methods),
family, explicit or implicit, symplectic, and whether the course teaches it. ``--json``
prints the same rows as one document.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mslab.commands.common import add_common_options, emit_json, say

if TYPE_CHECKING:
    import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab methods`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "methods",
        help="list the integrators: order, stages, family",
        description="The registered integrators (names for --method and --methods) with their order, "
                    "force evaluations per step, family and properties.",
    )
    add_common_options(p, out=False)
    p.set_defaults(func=run)


def rows() -> list[dict]:
    """One dict per registered method: name, order, stages, family, explicit, symplectic, course."""
    from mslab.integrators.base import get_method, methods

    out = []
    for name in methods():
        m = get_method(name)
        out.append({"method": m.name, "order": int(m.order), "stages": int(m.n_stages),
                    "family": getattr(m, "family", type(m).__name__), "explicit": bool(m.explicit),
                    "symplectic": bool(m.symplectic), "course": bool(getattr(m, "course", False))})
    return out


def run(args: argparse.Namespace) -> int:
    """Run ``mslab methods`` with the parsed ``args``; return the exit code."""
    table = rows()
    if args.json:
        emit_json({"methods": table})
        return 0
    header = ["method", "order", "stages", "family", "explicit", "symplectic", "course"]
    cells = [[r["method"], str(r["order"]), str(r["stages"]), r["family"],
              "yes" if r["explicit"] else "no", "yes" if r["symplectic"] else "no",
              "yes" if r["course"] else ""] for r in table]
    widths = [max(len(h), *(len(c[i]) for c in cells)) for i, h in enumerate(header)]
    say(args, "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip())
    for c in cells:
        say(args, "  ".join(v.ljust(w) for v, w in zip(c, widths, strict=True)).rstrip())
    say(args, "stages: force evaluations per step (implicit methods: per iteration); "
              "use a name with --method (run) or --methods (compare, precision)")
    return 0
