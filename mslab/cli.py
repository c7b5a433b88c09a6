"""The ``mslab`` command line.

Every user mistake ends as one line ``mslab: error: ...`` with exit code 2 and no
traceback; every subcommand takes ``--json`` and (where it writes) ``--out DIR``. Ctrl-C ends
with exit code 130 and one line at any moment (:mod:`mslab.interrupts`); a compilation by
numba is announced on stderr (not with ``--json``). When the reader of the output goes away
(``mslab methods | head -5``), the command ends quietly with exit code 141, as other tools do.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from mslab import interrupts
from mslab.commands.common import CommandError
from mslab.errors import MslabError, take_broken

#: subcommand modules in mslab.commands, in the order ``mslab --help`` lists them
COMMANDS = ("scenes", "methods", "run", "compare", "precision", "stability", "validate", "grade", "release",
            "bench")
#: exit code when the reader of the output has gone (a broken pipe): 128 + SIGPIPE, as a shell reports
EXIT_READER_LEFT = 141


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # argparse's own usage errors: one line, exit 2
        message = message.removeprefix("argument ")  # "--dt: must be > 0, got -1.0"
        self.exit(2, f"mslab: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """Return the ``mslab`` parser with every subcommand of :data:`COMMANDS`."""
    parser = _Parser(prog="mslab",
                     description="Mass-spring systems: integrators, stability, accuracy vs cost.")
    from mslab import __version__

    parser.add_argument("--version", action="version", version=f"mslab {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"mslab.commands.{name}")
        except ModuleNotFoundError as err:
            if err.name == f"mslab.commands.{name}":
                continue  # a command not built yet
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``mslab`` command line on ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    from mslab import jit  # (imports no numba)

    announcer = jit.announce_with(None)
    with interrupts.command_line():
        try:
            code = _main(argv)
            sys.stdout.flush()  # (what is still buffered: its reader may have left too)
        except BrokenPipeError:
            code = _reader_left()
        except KeyboardInterrupt:
            interrupts.finishing()
            print("mslab: interrupted", file=sys.stderr)
            code = interrupts.EXIT_INTERRUPTED
        finally:
            interrupts.finishing()
            jit.announce_with(announcer)
    return interrupts.leave(code)


def _main(argv: list[str] | None) -> int:
    for line in take_broken():  # a method or effect file that failed to load: the rest works
        print(f"mslab: warning: {line} (file skipped)", file=sys.stderr)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as done:  # a usage error (already printed as one line) returns its code
        if done.code in (0, None):  # --help, --version: argparse's own exit
            raise
        return int(done.code) if isinstance(done.code, int) else 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from mslab import jit
    from mslab.progress import compile_notice

    jit.announce_with(None if getattr(args, "json", False) else compile_notice)
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:
        return _reader_left()
    except (CommandError, MslabError, ValueError, OSError) as err:
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        if isinstance(err, OSError) and err.filename and err.strerror:  # not "[Errno 13] ...: 'path'"
            message = f"{err.filename}: {err.strerror.lower()}"
        print(f"mslab: error: {message}", file=sys.stderr)
        return 2


def _reader_left() -> int:
    """End quietly when the output's reader has gone (``mslab methods | head``), as other tools do.

    Later writes (the interpreter's last flush) go nowhere; the exit code is 141, a shell's
    code for a program ended by SIGPIPE.
    """
    import os

    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):  # a stdout without a file descriptor (a test's capture)
        pass
    return EXIT_READER_LEFT


if __name__ == "__main__":
    sys.exit(main())
