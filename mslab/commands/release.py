"""``mslab release [SRC] DEST``: write the student version of the exercises."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from mslab.commands.common import CommandError, add_common_options, emit_json, say
from mslab.grading.layout import default_source
from mslab.grading.release import release

if TYPE_CHECKING:
    import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab release`` subcommand to ``subparsers``."""
    p = subparsers.add_parser("release", help="write the student version of the exercises",
                              description="Copy SRC to DEST with every solution block replaced by "
                                          "'raise NotImplementedError', hidden tests left out and a "
                                          "student README; warns about markers it does not understand.")
    p.add_argument("paths", nargs="+", metavar="[SRC] DEST",
                   help="source folder (default exercises/) and target")
    p.add_argument("--force", action="store_true", help="replace DEST if it exists")
    add_common_options(p, out=False)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``mslab release`` with the parsed ``args``; return the exit code."""
    if len(args.paths) > 2:
        raise CommandError("expected [SRC] DEST", key="paths")
    if len(args.paths) == 2:
        src, dest = args.paths
    else:
        default = default_source()
        if default is None:
            raise CommandError("give SRC: this folder has no exercises/ with hidden tests", key="paths")
        src, dest = str(default), args.paths[0]
    warnings: list[str] = []
    try:
        files = release(src, dest, force=args.force, warnings=warnings)
    except ValueError as err:
        raise CommandError(str(err)) from None
    for line in warnings:
        print(f"mslab: warning: {line}", file=sys.stderr)
    if args.json:
        emit_json({"source": src, "release": dest, "files": [str(f) for f in files], "warnings": warnings})
    else:
        say(args, f"released {len(files)} files from {src} to {dest}")
    return 0
