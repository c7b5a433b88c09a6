"""``mslab grade SUBMISSION...``: grade submissions against all tests (public and hidden)."""

from __future__ import annotations

import csv
import os

from mslab.commands.common import CommandError, add_common_options, atomic_write, emit_json, say
from mslab.grading.autograde import format_report, grade, gradebook_rows
from mslab.grading.layout import default_source


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "grade", help="grade submissions (one folder, or a class folder of them)",
        description="Run every test (public and hidden, from --source) on each submission; student "
                    "code runs in a sandbox process with time and memory limits.")
    p.add_argument("submissions", nargs="+", metavar="SUBMISSION",
                   help="a submission folder (NN_topic/ inside) or a class folder <student>/")
    p.add_argument("--source", default=None, help="instructor's exercises with all tests"
                   "(default: exercises)")
    p.add_argument("--csv", metavar="FILE", default=None, help="write a gradebook (one row per student)")
    p.add_argument("--timeout", type=float, default=10.0, metavar="S", help="seconds per test (default 10)")
    p.add_argument("--memory", type=int, default=1024, metavar="MB", help="memory limit of student code")
    p.add_argument("--jobs", type=int, default=None, metavar="N", help="parallel runners (default: cores)")
    p.add_argument("--exercise", action="append", default=None, metavar="NAME",
                   help="grade only this exercise (repeatable)")
    add_common_options(p, out=False)
    p.set_defaults(func=run)


def run(args) -> int:
    if args.timeout <= 0:
        raise CommandError("must be positive", key="--timeout")
    if args.jobs is not None and args.jobs < 1:
        raise CommandError("must be at least 1", key="--jobs")
    try:
        results = grade(args.submissions, source=args.source or default_source(), jobs=args.jobs,
                        timeout=args.timeout, memory_mb=args.memory, only=args.exercise)
    except ValueError as err:
        raise CommandError(str(err)) from None
    if args.csv:
        def write(tmp: str) -> None:
            with open(tmp, "w", newline="") as fh:
                csv.writer(fh).writerows(gradebook_rows(results))
        atomic_write(args.csv, write)
    if args.json:
        docs = [r.to_dict() for r in results]
        emit_json(docs[0] if len(docs) == 1 else {"submissions": docs})
    else:
        for r in results:
            say(args, format_report(r))
        if len(results) > 1:
            say(args, "")
            for r in results:
                say(args, f"{r.student:<24} {r.total:g}/{r.max_points:g}")
    if args.csv:
        say(args, f"gradebook: {os.fspath(args.csv)}")
    return 0
