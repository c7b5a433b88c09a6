"""Ctrl-C that always ends cleanly: exit 130 and one line, or a KeyboardInterrupt where it is safe.

Python turns SIGINT into a ``KeyboardInterrupt`` raised at whatever line runs. Most of
mslab handles that (a run keeps the samples computed so far, files are written under a
temporary name and renamed), but numba does not: an interrupt raised while it compiles, or
loads compiled code from its cache, lands in its finalisers ("Exception ignored ...
KeyboardInterrupt", the Ctrl-C lost) or leaves a half-built library behind ("RuntimeError:
no compiled object yet"). Such work is therefore *protected* (:func:`protected`, used by
:mod:`mslab.jit` around every compilation or cache load and the import of numba):

* on the command line (:func:`command_line`, around ``mslab`` and ``make demo``), Ctrl-C in a
  protected section ends the process at once with exit code 130 and one line
  ``mslab: interrupted while compiling ...``: nothing was computed there, and every file
  written before is complete (atomic writes). Elsewhere it raises ``KeyboardInterrupt``
  (the run stops, keeps its samples and saves them; a Ctrl-C while saving leaves the files
  already complete and removes the one being written); once the command has its answer
  (:func:`finishing`), and while ``import mslab`` runs (:func:`starting`), a Ctrl-C ends
  the process the same way;
* in a program or notebook (Python's own SIGINT handler), Ctrl-C in a protected section
  is held until the section ends and then raised as ``KeyboardInterrupt``.

A process that ignores SIGINT when it starts (a background job of a shell script) keeps
ignoring it, as Python itself does.

For tests, ``MSLAB_TEST_INTERRUPT=PHASE`` makes the process send itself SIGINT when it enters
that phase (:func:`phase`: ``import``, ``loading numba``, ``compiling`` (or loading from the
cache), ``stepping``, ``saving``), so a test meets every phase without timing anything.

On the command line a watcher thread also wakes on SIGINT (Python's wakeup descriptor), so
a protected section ends at once even while numba is inside one long call to LLVM (Python
runs signal handlers only between its own instructions). The few milliseconds of the
interpreter's own start, before ``mslab`` is imported, are Python's.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

#: exit code of an interrupted command (128 + SIGINT)
EXIT_INTERRUPTED = 130

_state = {"cli": False, "raised": False, "process": False}
_exiting = threading.Lock()  # held by the one thread that ends the process
_protected: list[str] = []  # what the protected sections in progress are doing (outermost first)


def phase(name: str) -> None:
    """Enter phase ``name``: sends this process SIGINT when ``$MSLAB_TEST_INTERRUPT`` names it (tests)."""
    if os.environ.get("MSLAB_TEST_INTERRUPT") == name:
        os.kill(os.getpid(), signal.SIGINT)


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def exit_now(what: str | None = None) -> None:
    """Print ``mslab: interrupted [while WHAT]`` on stderr and end the process with exit code 130.

    ``os._exit``: no Python code runs after it (no half-finished cleanup can print a traceback);
    files are never half-written because every output is written under a temporary name first.
    """
    _exiting.acquire()  # the watcher thread and the handler may both get here: one line only
    line = "mslab: interrupted" + (f" while {what}" if what else "") + "\n"
    try:
        os.write(2, line.encode())
    finally:
        os._exit(EXIT_INTERRUPTED)


def _cli_handler(signum: int, frame: object) -> None:
    if _protected:
        exit_now(_protected[0])
    _state["raised"] = True
    raise KeyboardInterrupt


def _exit_handler(signum: int, frame: object) -> None:
    exit_now(_protected[0] if _protected else None)


def starting() -> None:
    """On the command line, make Ctrl-C during ``import mslab`` end with exit 130 and one line.

    Called first thing by ``mslab/__init__.py``; acts when the process is the ``mslab`` command
    or ``python -m mslab...``. :func:`command_line` takes over while the command runs.
    """
    if _main_thread() and _is_command_line() and signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        _state["cli"] = _state["process"] = True
        signal.signal(signal.SIGINT, _exit_handler)
        phase("import")


@contextmanager
def command_line() -> Iterator[None]:
    """Run a command (``mslab``, ``make demo``): Ctrl-C raises KeyboardInterrupt once, except when protected.

    On leaving, the previous SIGINT handler comes back (the exit handler of :func:`starting`
    in the ``mslab`` process, Python's own when a test calls the command in its process).
    """
    if not _main_thread() or signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        yield  # a process told to ignore Ctrl-C (a background job of a script) keeps ignoring it
        return
    saved = (_state["cli"], _state["raised"])
    _state["cli"], _state["raised"] = True, False
    previous = signal.signal(signal.SIGINT, _cli_handler)
    watcher = _watch_wakeup()
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if watcher is not None:
            watcher()
        _state["cli"], _state["raised"] = saved


def finishing() -> None:
    """Mark that the command has its answer: from now on Ctrl-C only ends the process (exit 130, one line)."""
    if _main_thread() and _state["cli"]:
        signal.signal(signal.SIGINT, _exit_handler)


def leave(code: int) -> int:
    """Return the command's exit code; an interrupted ``mslab`` process ends here with 130.

    Its answer is printed: it ends now (streams flushed, ``os._exit``), since CPython may
    otherwise report a KeyboardInterrupt caught inside an import as the process's cause of
    death (killed by SIGINT, not exit 130). A command called in a Python process returns.
    """
    if code == EXIT_INTERRUPTED and _state["process"] and _main_thread():
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(EXIT_INTERRUPTED)
    return code


def was_interrupted() -> bool:
    """Whether the command line's handler has raised KeyboardInterrupt in this command."""
    return _state["raised"]


@contextmanager
def protected(what: str) -> Iterator[None]:
    """Run work that a KeyboardInterrupt must not land in (numba compiling or loading, an import).

    ``what`` says what is being done ("compiling the rk4 loop"); it ends the command line's
    one-line message. In a program with Python's own handler, a Ctrl-C here is raised as
    KeyboardInterrupt when the section ends.
    """
    held: list[int] = []
    previous = None
    if _main_thread() and not _state["cli"] and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    _protected.append(what)
    try:
        phase(what.split(" ")[0] if what.startswith("compiling") else what)
        yield
    finally:
        _protected.pop()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if held:
        raise KeyboardInterrupt


def _watch_wakeup() -> Callable[[], None] | None:
    """Wake on SIGINT in a thread, which ends the process at once in a protected section.

    Python's C-level handler writes the signal number to the wakeup file descriptor as soon as
    the signal arrives; the Python handler itself waits until the main thread runs Python code
    again, which it does not while numba is inside one long call to LLVM. Returns the function
    that stops watching (None: no wakeup descriptor on this platform).
    """
    import socket

    try:
        read, write = socket.socketpair()
        write.setblocking(False)
        previous = signal.set_wakeup_fd(write.fileno(), warn_on_full_buffer=False)
    except (OSError, ValueError):
        return None

    def watch() -> None:
        while True:
            try:
                data = read.recv(64)
            except OSError:
                return
            if not data:
                return
            if signal.SIGINT in data and _protected and _state["cli"]:
                exit_now(_protected[0])

    thread = threading.Thread(target=watch, name="mslab-interrupt", daemon=True)
    thread.start()

    def stop() -> None:
        signal.set_wakeup_fd(previous)
        write.close()  # the watcher's recv returns b""
        thread.join()
        read.close()

    return stop


def _is_command_line() -> bool:
    """Whether this process is ``mslab ...`` or ``python -m mslab[.something] ...``."""
    if os.path.basename(sys.argv[0] if sys.argv else "") == "mslab":
        return True
    args = list(getattr(sys, "orig_argv", sys.argv))[1:]
    for n, arg in enumerate(args):
        if arg == "-m":
            module = args[n + 1] if n + 1 < len(args) else ""
            return module == "mslab" or module.startswith("mslab.")
        if arg.startswith("-m"):
            module = arg[2:]
            return module == "mslab" or module.startswith("mslab.")
        if not arg.startswith("-"):
            return False
    return False
