"""``mslab release [SRC] DEST``: write the student version of the exercises (and platform packages)."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from mslab.commands.common import CommandError, add_common_options, emit_json, say
from mslab.grading.layout import default_source
from mslab.grading.packages import build_gradescope, build_prairielearn
from mslab.grading.release import release, release_course

if TYPE_CHECKING:
    import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab release`` subcommand to ``subparsers``."""
    p = subparsers.add_parser("release", help="write the student version of the exercises",
                              description="Copy SRC to DEST with every solution block replaced by "
                                          "'raise NotImplementedError', hidden tests left out and a "
                                          "student README; warns about markers it does not understand. "
                                          "--gradescope / --prairielearn write a platform's grader "
                                          "package instead of (or besides) DEST.")
    p.add_argument("paths", nargs="*", metavar="[SRC] DEST",
                   help="source folder (default exercises/) and target; with --gradescope or "
                        "--prairielearn, one path is SRC")
    p.add_argument("--gradescope", metavar="DIR", default=None,
                   help="write a Gradescope autograder (setup.sh, run_autograder; DIR.zip to upload)")
    p.add_argument("--prairielearn", metavar="DIR", default=None,
                   help="write a PrairieLearn external grader (Dockerfile, serverFilesCourse/, info.json)")
    p.add_argument("--lessons", metavar="DIR", default=None,
                   help="write a course kit: the lessons of DIR in DEST, the exercises in DEST/student "
                        "(what students need, without the course repository)")
    p.add_argument("--exercise", action="append", default=None, metavar="NAME",
                   help="package only this exercise (repeatable; default all)")
    p.add_argument("--force", action="store_true", help="replace DEST (or DIR) if it exists")
    add_common_options(p, out=False)
    p.set_defaults(func=run)


def _paths(args: argparse.Namespace) -> tuple[str, str | None]:
    """Return SRC and DEST; with a platform package asked for, one path is SRC and DEST is optional."""
    packages, n = bool(args.gradescope or args.prairielearn), len(args.paths)
    if n > 2 or (n == 0 and not packages):
        raise CommandError("expected [SRC] DEST", key="paths")
    src = args.paths[0] if n == 2 or (n == 1 and packages) else None
    dest = args.paths[-1] if n == 2 or (n == 1 and not packages) else None
    if src is None:
        default = default_source()
        if default is None:
            raise CommandError("give SRC: this folder has no exercises/ with hidden tests", key="paths")
        src = str(default)
    return src, dest


def run(args: argparse.Namespace) -> int:
    """Run ``mslab release`` with the parsed ``args``; return the exit code."""
    src, dest = _paths(args)
    if args.exercise and dest is not None:
        raise CommandError("--exercise applies to --gradescope / --prairielearn only", key="--exercise")
    if args.lessons and dest is None:
        raise CommandError("--lessons needs DEST, the kit's folder", key="--lessons")
    warnings: list[str] = []
    doc: dict = {"source": src, "warnings": warnings}
    try:
        if dest is not None and args.lessons:
            files = release_course(src, args.lessons, dest, force=args.force, warnings=warnings)
            doc.update(release=dest, files=[str(f) for f in files])
            say(args, f"course kit: {len(files)} files in {dest} (lessons from {args.lessons}, "
                      f"exercises from {src} in {dest}/student)")
        elif dest is not None:
            files = release(src, dest, force=args.force, warnings=warnings)
            doc.update(release=dest, files=[str(f) for f in files])
            say(args, f"released {len(files)} files from {src} to {dest}")
        for key, build in (("gradescope", build_gradescope), ("prairielearn", build_prairielearn)):
            target = getattr(args, key)
            if target:
                files = build(src, target, only=args.exercise, force=args.force)
                doc[key] = {"folder": target, "files": [str(f) for f in files]}
                say(args, f"{key}: {len(files)} files in {target}"
                          + (f" (upload {target.rstrip('/')}.zip)" if key == "gradescope" else ""))
    except ValueError as err:
        raise CommandError(str(err)) from None
    for line in warnings:
        print(f"mslab: warning: {line}", file=sys.stderr)
    if args.json:
        emit_json(doc)
    return 0
