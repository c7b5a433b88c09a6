"""Feedback by the clock: a progress line that appears once work has taken about two seconds.

A :class:`Progress` counts units of work (steps, runs, frames) and is redrawn by a small
background thread, so the line moves and its clock runs even while one long step, one
method of a sweep or one frame of an animation is computing. It shows nothing on a pipe or
in a file (only on a terminal), and nothing for work that ends within ``delay`` seconds,
whatever its step count. Lines printed through :meth:`Progress.write` (warnings, notes)
appear above the bar at the moment they arise.

``on_estimate`` (optional) is called once, from the thread, with the estimated total
seconds, as soon as the first ``estimate_after`` seconds of work give a rate: the run
command prints it as "about 40 s (from the first 120 steps)".

:func:`compile_notice` is how the command line announces a compilation by numba (set with
:func:`mslab.jit.announce_with`): one line at once (what is compiled, that it happens
once, where it is cached), then the clock on the progress line of the work in progress, or
on a line of its own.
"""

from __future__ import annotations

import shutil
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TextIO

#: seconds of work before the bar appears
DELAY = 2.0
#: seconds between redraws
INTERVAL = 0.2
#: seconds of work before the time estimate is made
ESTIMATE_AFTER = 1.0


def is_terminal(stream: TextIO) -> bool:
    """Whether ``stream`` is an interactive terminal (False for pipes, files, closed streams)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


def duration(seconds: float) -> str:
    """``"13 ms"``, ``"4.2 s"``, ``"38 s"``, ``"4 min 10 s"``, ``"2 h 05 min"``."""
    if seconds < 1:
        return f"{seconds * 1e3:.2g} ms" if seconds < 0.01 else f"{seconds * 1e3:.0f} ms"
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, secs = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes} min {secs:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


class Progress:
    """A progress line on a terminal, drawn by the clock (see the module docstring).

    Parameters
    ----------
    total : int, optional
        Units of work expected (None: unknown, the line shows the count and the clock).
    desc : str
        What is being done (e.g. the current method); change it with :meth:`describe`.
    unit : str
        Name of one unit of work ("step", "run", "frame").
    stream : text stream, optional
        Where the line is drawn; default ``sys.stderr``.
    enabled : bool, optional
        Draw the line; default: only when ``stream`` is a terminal.
    delay, interval : float
        Seconds before the line appears and between redraws.
    on_estimate : callable, optional
        ``on_estimate(total_seconds, units_done)``, called once after ``estimate_after``
        seconds when at least one unit is done and more than a second of work remains.
    clock : callable, optional
        The clock in seconds (default ``time.perf_counter``; tests pass their own and call
        :meth:`tick` instead of waiting).
    """

    def __init__(self, total: int | None = None, desc: str = "", unit: str = "step", *,
                 stream: TextIO | None = None, enabled: bool | None = None, delay: float = DELAY,
                 interval: float = INTERVAL, on_estimate: Callable[[float, int], None] | None = None,
                 estimate_after: float = ESTIMATE_AFTER, clock: Callable[[], float] = time.perf_counter):
        self.clock = clock
        self.stream = sys.stderr if stream is None else stream
        self.enabled = is_terminal(self.stream) if enabled is None else bool(enabled)
        self.total, self.desc, self.unit = total, desc, unit
        self.n = 0
        self._first = None  # (time, count) after the first update: one-time costs end there
        self.delay, self.interval = delay, interval
        self.on_estimate, self.estimate_after = on_estimate, estimate_after
        self._estimated = on_estimate is None
        self.start = clock()
        self.shown = False
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._thread = None
        _open.append(self)
        if self.enabled or on_estimate is not None:
            self._thread = threading.Thread(target=self._watch, name="mslab-progress", daemon=True)
            self._thread.start()

    # -- counting ---------------------------------------------------------------------------------
    def update(self, n: int = 1) -> None:
        """``n`` more units done (cheap: called once per step by ``simulate``)."""
        self.n += n
        if self._first is None:
            self._first = (self.clock(), self.n)
            from mslab.interrupts import phase

            phase("stepping")  # (tests: a Ctrl-C while stepping)

    def describe(self, desc: str, total: int | None = None) -> None:
        """Change what the line says is being done (and, optionally, the total)."""
        self.desc = desc
        if total is not None:
            self.total = total

    @property
    def elapsed(self) -> float:
        """Seconds since the progress started."""
        return self.clock() - self.start

    def estimate(self) -> float | None:
        """Estimated total seconds from the rate so far (None before the first unit).

        The rate is measured after the first update, so a slow first unit (imports,
        compilation, caches) counts once, not once per unit.
        """
        if not self.total or self.n <= 0 or self._first is None:
            return None
        now = self.clock()
        t1, n1 = self._first
        if self.n <= n1 or now - t1 <= 0:
            return (now - self.start) * self.total / self.n
        return (t1 - self.start) + (now - t1) * (self.total - n1) / (self.n - n1)

    def measured(self) -> int:
        """Units the current rate was measured on (after the first update)."""
        return self.n - self._first[1] if self._first is not None else 0

    def line(self) -> str:
        """Return the text of the progress line."""
        elapsed = self.elapsed
        head = f"{self.desc}: " if self.desc else ""
        if self.total:
            frac = min(1.0, self.n / self.total)
            width = 20
            bar = "#" * int(frac * width) + "-" * (width - int(frac * width))
            left = self.estimate()
            eta = f", about {duration(max(0.0, left - elapsed))} left" if left is not None else ""
            return (f"{head}[{bar}] {100 * frac:3.0f}% {self.n}/{self.total} {self.unit}s "
                    f"({duration(elapsed)}{eta})")
        if self.n == 0:
            return f"{head}... ({duration(elapsed)})"
        return f"{head}{self.n} {self.unit}s ({duration(elapsed)})"

    # -- drawing ----------------------------------------------------------------------------------
    def _watch(self) -> None:
        while not self._stop.wait(self.interval):
            self.tick()

    def tick(self) -> None:
        """Do what the clock asks now: the estimate once it is due, the line once ``delay`` has passed."""
        elapsed = self.elapsed
        if not self._estimated and elapsed >= self.estimate_after and self.measured() > 0:
            self._estimated = True
            total = self.estimate()
            if total is not None and total - elapsed > 1.0:
                with self._lock:
                    self.on_estimate(total, self.n)
        if self.enabled and elapsed >= self.delay:
            self._draw()

    def _draw(self) -> None:
        with self._lock:
            if self._stop.is_set():
                return
            width = max(20, shutil.get_terminal_size((80, 24)).columns - 1)
            self.stream.write("\r" + self.line()[:width] + "\x1b[K")
            self.stream.flush()
            self.shown = True

    def _clear(self) -> None:
        if self.shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()

    def write(self, text: str, file: TextIO | None = None) -> None:
        """Print a line above the progress line (on ``file``, default the bar's stream)."""
        with self._lock:
            self._clear()
            sys.stdout.flush()  # lines already printed on stdout come first
            target = self.stream if file is None else file
            print(text, file=target, flush=True)
            self.shown = False
        if self.enabled and self.elapsed >= self.delay and not self._stop.is_set():
            self._draw()

    def close(self) -> None:
        """Stop the clock and remove the line (idempotent)."""
        self._stop.set()
        if self in _open:
            _open.remove(self)
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
            self._thread = None
        with self._lock:
            self._clear()
            self.shown = False

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


#: progress lines not closed yet, newest last (where a compilation notice goes)
_open: list[Progress] = []


@contextmanager
def compile_notice(what: str, where: str, stream: TextIO | None = None) -> Iterator[None]:
    """Announce a compilation while it runs (the command line's :func:`mslab.jit.announce_with`).

    Prints ``mslab: compiling WHAT (once: cached in WHERE for later runs)`` at once, on
    ``stream`` (default ``sys.stderr``), above the progress line of the work in progress
    if there is one, whose description then says "compiling" until the compilation ends;
    otherwise a line of its own counts the seconds on a terminal (nothing more on a pipe).
    """
    line = f"mslab: compiling {what} (once: cached in {where} for later runs) ..."
    bar = _open[-1] if _open else None
    if bar is not None:
        bar.write(line)
        desc = bar.desc
        bar.describe(f"{desc} (compiling)" if desc else "compiling")
        try:
            yield
        finally:
            bar.describe(desc)
        return
    target = sys.stderr if stream is None else stream
    print(line, file=target, flush=True)
    with Progress(None, "compiling", stream=target):
        yield


def make_progress(progress: Any, total: int, desc: str, unit: str = "step") -> tuple[Progress | None, bool]:
    """Return the progress object a long computation reports to, and whether the caller owns it.

    ``progress`` is None (a :class:`Progress` drawn only on a terminal), True (always
    drawn), False (none) or an object with ``update(n)`` given by the caller (a sweep's
    bar shared by its runs; the caller closes it).
    """
    if progress is None or progress is True:
        return Progress(total, desc, unit, enabled=True if progress else None), True
    if progress is False:
        return None, False
    check_progress(progress)
    return progress, False


def check_progress(progress: object) -> None:
    """Refuse a ``progress`` other than None, True, False or an object with ``update(n)`` (TypeError)."""
    if progress is None or isinstance(progress, bool) or callable(getattr(progress, "update", None)):
        return
    from mslab.checks import shown

    raise TypeError(f"progress must be True, False, None or an object with an update(n) method, "
                    f"got {type(progress).__name__} {shown(progress)}")
