"""``mslab release [SRC] DEST``: write the student version of the exercises."""

from __future__ import annotations

from mslab.commands.common import CommandError, add_common_options, emit_json, say
from mslab.grading.layout import default_source
from mslab.grading.release import release


def register(subparsers) -> None:
    p = subparsers.add_parser("release", help="write the student version of the exercises",
                              description="Copy SRC to DEST with every solution block replaced by "
                                          "'raise NotImplementedError' and hidden tests left out.")
    p.add_argument("paths", nargs="+", metavar="[SRC] DEST",
                   help="source folder (default exercises/) and target")
    p.add_argument("--force", action="store_true", help="replace DEST if it exists")
    add_common_options(p, out=False)
    p.set_defaults(func=run)


def run(args) -> int:
    if len(args.paths) > 2:
        raise CommandError("expected [SRC] DEST", key="paths")
    src, dest = (args.paths if len(args.paths) == 2 else [str(default_source()), args.paths[0]])
    try:
        files = release(src, dest, force=args.force)
    except ValueError as err:
        raise CommandError(str(err)) from None
    if args.json:
        emit_json({"source": src, "release": dest, "files": [str(f) for f in files]})
    else:
        say(args, f"released {len(files)} files from {src} to {dest}")
    return 0
