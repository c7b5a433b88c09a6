"""``mslab grade SUBMISSION...``: grade submissions against all tests (public and hidden)."""

from __future__ import annotations

import os
import resource
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from mslab.commands.common import CommandError, add_common_options, count, emit_json, number, say
from mslab.grading.autograde import SubmissionResult, grade, grader_faults
from mslab.grading.isolation import DESCRIPTION
from mslab.grading.layout import default_source, expand_submissions, find_exercises
from mslab.grading.platforms import FORMATS, SINGLE, check_format, write_grades
from mslab.grading.report import Journal, format_report, printable

if TYPE_CHECKING:
    import argparse

#: smallest --timeout (CPU seconds; the runner measures CPU time every 0.05-0.2 s)
MIN_TIMEOUT = 0.1
#: largest --timeout (CPU seconds per test: a day; beyond, the limits' clocks overflow)
MAX_TIMEOUT = 86400.0
#: smallest --memory (MB)
MIN_MEMORY = 64
#: largest --memory (MB): 1 TiB (the grader's own hard address-space limit may lower it)
MAX_MEMORY = 1 << 20
#: largest --jobs (parallel runners, each a process and a cgroup)
MAX_JOBS = 256
#: seconds of grading before a progress line appears (on a terminal only)
PROGRESS_AFTER = 2.0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``mslab grade`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "grade", help="grade submissions (one folder, or a class folder of them)",
        description="Run every test (public and hidden, from --source) on each submission; student "
                    "code runs isolated by the operating system where it can (namespaces), with time "
                    "and memory limits.")
    p.add_argument("submissions", nargs="+", metavar="SUBMISSION",
                   help="a submission folder (NN_topic/FILE inside, or FILE itself with --exercise) "
                        "or a class folder (see --layout)")
    p.add_argument("--source", default=None,
                   help="the instructor's exercises with all tests (required unless the current "
                        "folder holds them as exercises/)")
    p.add_argument("--csv", "--output", dest="csv", metavar="FILE", default=None,
                   help="write the grades (--format: a gradebook CSV by default)")
    p.add_argument("--format", default="csv", choices=FORMATS,
                   help="what --output holds: mslab's gradebook (csv), Gradescope's or PrairieLearn's "
                        "results.json (one submission), a Canvas gradebook import (canvas)")
    p.add_argument("--assignment", default=None, metavar="TITLE",
                   help="--format canvas: the assignment column, 'Title (canvas id)' or a new title")
    p.add_argument("--journal", metavar="FILE", default=None,
                   help="record each result as it arrives (default with --csv: FILE.journal)")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted grading from its journal")
    p.add_argument("--timeout", type=number(minimum=MIN_TIMEOUT, maximum=MAX_TIMEOUT), default=10.0,
                   metavar="S",
                   help="CPU seconds per test, all the sandbox's processes together (default 10; "
                        "a wall-clock backstop of 5x+10 s)")
    p.add_argument("--memory", type=count(MIN_MEMORY, MAX_MEMORY), default=1024, metavar="MB",
                   help="memory limit of student code")
    p.add_argument("--jobs", type=count(1, MAX_JOBS), default=None, metavar="N",
                   help="parallel runners (default: cores)")
    p.add_argument("--exercise", action="append", default=None, metavar="NAME",
                   help="grade only this exercise (repeatable)")
    p.add_argument("--layout", default="auto", choices=["auto", "class", "submission"],
                   help="class: every entry of SUBMISSION is a student's (folder, .zip, .py, .ipynb); "
                        "submission: SUBMISSION is one student's work; auto (default): one submission "
                        "if it holds an exercise's file (NN_topic/FILE or FILE itself), else a class; "
                        "refused if it also holds entries that look like other students'")
    p.add_argument("--isolation", default="auto", choices=["auto", "bwrap", "namespaces", "rlimits"],
                   help="how student code is isolated (default: the strongest available)")
    p.add_argument("--require-isolation", action="store_true",
                   help="refuse to grade where the machine offers no namespaces or no cgroup per sandbox")
    add_common_options(p, out=False)
    p.set_defaults(func=run)


class Progress:
    """``grading: 37/240 items`` on stderr, once grading has taken 2 s, on a terminal only."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.start = time.monotonic()
        self.shown = False

    def __call__(self, done: int, total: int) -> None:
        """Show ``done`` of ``total`` items (once 2 s have passed, on a terminal)."""
        if not self.enabled or time.monotonic() - self.start < PROGRESS_AFTER:
            return
        elapsed = time.monotonic() - self.start
        sys.stderr.write(f"\rgrading: {done}/{total} items ({elapsed:.0f} s)   ")
        sys.stderr.flush()
        self.shown = True

    def close(self) -> None:
        """Erase the progress line if one was shown."""
        if self.shown:
            sys.stderr.write("\r" + " " * 50 + "\r")
            sys.stderr.flush()


def _check_options(args: argparse.Namespace) -> None:
    """Refuse bad limits and gradebook paths in one line, before anything runs."""
    try:
        check_format(args.format, args.csv, len(args.submissions), args.assignment)
    except ValueError as err:
        raise CommandError(str(err)) from None
    hard = resource.getrlimit(resource.RLIMIT_AS)[1]
    if hard != resource.RLIM_INFINITY and args.memory * 1024 * 1024 > hard:
        raise CommandError(f"this process's own address-space limit is {hard // (1024 * 1024)} MB "
                           "(ulimit -v): no sandbox can be given more", key="--memory")
    _check_outputs(args)


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse an output that is no regular file, or the same file as another output or a submission."""
    journal = args.journal or (f"{args.csv}.journal" if args.csv else None)
    outputs = [("--csv", args.csv), ("--journal", journal)]
    for key, path in outputs:
        if path is None:
            continue
        target = Path(path)
        if os.path.lexists(target) and (target.is_symlink() or not target.is_file()):
            raise CommandError("must be a regular file or a new one", where=str(path), key=key)
        folder = target.parent if str(target.parent) else Path(".")
        if not folder.is_dir() or not os.access(folder, os.W_OK | os.X_OK):
            raise CommandError("its folder is missing or not writable", where=str(path), key=key)
    taken = [("a SUBMISSION", path) for path in args.submissions]
    for key, path in outputs:
        if path is None:
            continue
        for other, seen in taken:
            if _same_file(path, seen):
                raise CommandError(f"is the same file as {other} ({seen}): one would destroy the other",
                                   where=str(path), key=key)
        taken.append((key, path))
        inside = any(Path(path).resolve().parent == Path(sub).resolve() for sub in args.submissions)
        if inside and os.path.lexists(path) and str(path).endswith((".py", ".ipynb", ".zip")):
            raise CommandError("is a student's entry of the class folder", where=str(path), key=key)


def _same_file(a: str | Path, b: str | Path) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _check_single(args: argparse.Namespace, source: str | Path) -> None:
    """Refuse a one-submission format (Gradescope, PrairieLearn) for a class, before grading anything."""
    if args.format not in SINGLE:
        return
    try:
        exercises = find_exercises(source)
        exercises = [e for e in exercises if not args.exercise or e.name in args.exercise] or exercises
        found = expand_submissions(args.submissions, exercises, args.layout, ignore=[args.csv])
    except ValueError as err:
        raise CommandError(str(err)) from None
    if len(found) != 1:
        raise CommandError(f"{args.format} writes the results.json of one submission; "
                           f"{len(found)} submissions were found (a class: grade it with --format csv "
                           "or canvas)", key="--format")


def _warn_isolation(result: SubmissionResult) -> None:
    """One line naming the isolation in force and what it leaves unprotected."""
    if result.isolation == DESCRIPTION["rlimits"]:
        why = ("chosen with --isolation rlimits" if result.isolation_asked == "rlimits"
               else "no bwrap and no user namespaces on this machine")
        who = ("as a throwaway uid, in your file system with per-process limits only (no namespaces: "
               "it can read what other users may read and share /tmp with classmates)" if os.geteuid() == 0
               else "as your user, in your file system with per-process limits only (no namespaces: it can "
               "read what your user can read, the hidden tests and classmates' files included; without a "
               "cgroup per sandbox, one student at a time, as they share your user's process limit)")
        print(f"mslab: warning: isolation is rlimits ({why}): student code ran {who}; use "
              "--require-isolation to refuse", file=sys.stderr)
    elif result.resources.startswith("no cgroup"):
        print(f"mslab: warning: {result.resources}: a sandbox's processes, memory and CPU share are "
              "not capped as a whole; use --require-isolation to refuse", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Run ``mslab grade`` with the parsed ``args``; return the exit code."""
    _check_options(args)
    source = args.source or default_source()
    if source is None:
        raise CommandError("--source is required: the instructor's exercises folder (with the hidden "
                           "tests); this folder has no exercises/ with hidden tests")
    _check_single(args, source)
    journal = args.journal or (f"{args.csv}.journal" if args.csv else None)
    if args.resume and not journal:
        raise CommandError("--resume needs --csv or --journal (where the interrupted grading wrote)")
    if args.resume and not Path(journal).is_file():
        raise CommandError(f"{journal}: no journal to resume from")
    try:
        book = Journal(journal, args.resume) if journal else None
    except ValueError as err:
        raise CommandError(str(err)) from None
    try:
        results = _grade(args, source, book)
        _refuse_grader_faults(results, book)
        if args.csv:
            try:
                write_grades(args.csv, args.format, results, assignment=args.assignment)
            except ValueError as err:
                raise CommandError(str(err), where=os.fspath(args.csv)) from None
        if book is not None:
            book.close(finished=True)  # the class is graded: nothing to resume
    except CommandError:
        if book is not None and not args.resume and not book.added:
            book.close(finished=True)  # refused before anything was graded: nothing to resume
        raise
    finally:
        if book is not None:
            book.close(finished=False)
    if results:
        _warn_isolation(results[0])
    _show(args, results)
    return 0


def _refuse_grader_faults(results: list, book: Journal | None) -> None:
    """Stop (no gradebook, no journal to resume) when every test failed for a reason of the grader's own.

    Then the grader is misconfigured (a limit the system cannot honour), and a gradebook would
    be a class of zeros. When only some tests did (a sandbox that could not start after others
    ran: a student may have caused it), the gradebook is written and a warning names them, so
    that no student can stop the class's grading.
    """
    faults = grader_faults(results)
    if not faults:
        return
    total = sum(len(e.tests) for r in results for e in r.exercises)
    first = printable(faults[0], 300)
    if len(faults) < total:
        print(f"mslab: warning: {len(faults)} test(s) failed for a reason of the grader's own, not the "
              f"students' (first: {first}); their marks are not the students': grade them again",
              file=sys.stderr)
        return
    if book is not None:
        book.close(finished=True)  # its outcomes are the grader's failures: never to be resumed
    raise CommandError(f"{len(faults)} test(s) failed for a reason of the grader's own, not the students' "
                       f"(first: {first}); no gradebook written: fix it and grade again")


def _grade(args: argparse.Namespace, source: str | Path, book: Journal | None) -> list:
    progress = Progress(sys.stderr.isatty() and not args.json)
    try:
        return grade(args.submissions, source=source, jobs=args.jobs, timeout=args.timeout,
                     memory_mb=args.memory, only=args.exercise, isolation=args.isolation,
                     require_isolation=args.require_isolation, journal=book, resume=args.resume,
                     progress=progress, layout=args.layout,
                     ignore=[p for p in (args.csv, book.path if book else None) if p])
    except ValueError as err:
        raise CommandError(str(err)) from None
    except KeyboardInterrupt:
        progress.close()
        hint = (f"the items graded so far are in {book.path}: run the same command with --resume "
                "to continue" if book is not None else
                "grade with --csv FILE (or --journal FILE) to be able to continue with --resume")
        print(f"mslab: grading interrupted; {hint}", file=sys.stderr)
        raise
    finally:
        progress.close()


def _show(args: argparse.Namespace, results: list) -> None:
    if args.json:
        docs = [r.to_dict() for r in results]
        emit_json(docs[0] if len(docs) == 1 else {"submissions": docs})
    else:
        for r in results:
            say(args, format_report(r))
        if len(results) > 1:
            say(args, "")
            for r in results:
                say(args, f"{printable(r.student, 24):<24} {r.total:g}/{r.max_points:g}")
    if args.csv:
        say(args, f"gradebook: {os.fspath(args.csv)}")
