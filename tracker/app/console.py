"""How the command line talks to its user: the program's name, log lines and progress bars on stderr, and the one
form of every refusal.

The packages log through the standard :mod:`logging` module, one logger per module (``logging.getLogger(__name__)``),
and never configure it: a program that imports them decides what is shown. The command line does so once
(:func:`configure_logging`): informational lines (what was read, what was chosen, timings, summaries) at INFO,
shown by default; ``--quiet`` shows warnings only, ``--verbose`` debug lines too. What says how well a command's
job went is its result and goes to stdout, apart from the log: ``track``'s and ``demo``'s errors, ``compare``'s
tables, ``train``'s fit, ``convert``'s retarget residual. Progress counts as informational: it shows exactly
when INFO lines do (:func:`progress_bar`), as a bar on a terminal and as a plain line now and then in a log.

A command stopped by SIGTERM (``kill``, ``docker stop``, a cluster's preemption) is stopped as by Ctrl-C
(:func:`stop_signals`): it keeps what it can resume from, says so in one line and exits with 143 (130 for Ctrl-C).
"""
from __future__ import annotations

import logging
import math
import signal
import sys
import threading
import time
import weakref
from contextlib import contextmanager
from typing import Any, Iterator

#: The command's name in usage lines, help texts and messages, however it was started (``pose-tracker`` or
#: ``python -m tracker``).
PROG = "pose-tracker"
#: The packages whose loggers the command line configures.
PACKAGES = ("tracker", "priors", "likelihoods", "data_tools")


class _StderrHandler(logging.StreamHandler):
    """A handler writing to whatever ``sys.stderr`` is at the time of each record (so a redirected or captured
    stderr receives the lines, as ``print(file=sys.stderr)`` would)."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    @property
    def stream(self):  # type: ignore[override]
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:  # the base class assigns it; the property always answers sys.stderr
        pass


class _Formatter(logging.Formatter):
    """INFO lines as they are; warnings and errors as ``pose-tracker: warning: ...``; debug lines with their
    logger's name."""

    def format(self, record: logging.LogRecord) -> str:
        message = record.getMessage()
        if record.levelno >= logging.WARNING:
            return f"{PROG}: {record.levelname.lower()}: {message}"
        if record.levelno < logging.INFO:
            return f"{record.name}: {message}"
        return message


_handler: logging.Handler | None = None


def verbosity(quiet: bool = False, verbose: bool = False) -> int:
    """The logging level of ``--quiet`` (WARNING), ``--verbose`` (DEBUG) or neither (INFO)."""
    return logging.WARNING if quiet else logging.DEBUG if verbose else logging.INFO


def configure_logging(level: int = logging.INFO) -> None:
    """Show the packages' log lines at ``level`` and above on stderr: one handler on each package's logger, added
    on the first call; a later call (``main`` run again in one process) only changes the level. Only the command
    line calls this; the API leaves logging to the program that imports it."""
    global _handler
    if _handler is None:
        _handler = _StderrHandler()
        _handler.setFormatter(_Formatter())
        for name in PACKAGES:
            logging.getLogger(name).addHandler(_handler)
    for name in PACKAGES:
        logging.getLogger(name).setLevel(level)


def shows_progress() -> bool:
    """Whether progress bars are shown: when the packages' INFO lines are (not under ``--quiet``, and not when
    the API runs in a program that did not ask for INFO lines)."""
    return logging.getLogger(PACKAGES[0]).isEnabledFor(logging.INFO)


def on_terminal() -> bool:
    """Whether stderr is a terminal (where progress is a bar redrawn in place), not a file or a pipe (a log)."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):  # closed or replaced by an object without a file behind it
        return False


#: The bars drawn so far that may still be open: closed before an error or an interruption is reported, so that
#: no bar is drawn again below it (:func:`close_bars`).
_bars: weakref.WeakSet = weakref.WeakSet()


def progress_bar(iterable: Any = None, shown: bool | None = None, **options) -> Any:
    """Progress on stderr, shown when ``shown`` (default :func:`shows_progress`): on a terminal a ``tqdm`` bar,
    in a log (stderr redirected) a :class:`ProgressLines` that writes a plain line now and then. ``options`` are
    tqdm's (``total``, ``initial``, ``desc``, ``unit``)."""
    shown = shows_progress() if shown is None else shown
    if shown and not on_terminal():
        return ProgressLines(iterable, **options)
    from tqdm import tqdm

    bar = tqdm(iterable, disable=not shown, **options)
    _bars.add(bar)
    return bar


def close_bars() -> None:
    """Close every progress bar still open (each is drawn a last time), so that the line written next (an error,
    an interruption) is the last one on the terminal."""
    for bar in list(_bars):
        bar.close()


class ProgressLines:
    """Progress in a log: a plain line (``desc: n/total units (p%), rate, postfix``) at most every
    :attr:`STEP` of the work or :attr:`EVERY` seconds, and never twice within :attr:`QUIET` seconds; a last
    line when closed. The part of tqdm's interface the commands use: iteration, ``update``, ``n``,
    ``set_postfix``, ``set_postfix_str``, ``close`` and ``with``."""

    #: The share of the work between two lines (10%).
    STEP = 0.1
    #: The longest time between two lines (s).
    EVERY = 60.0
    #: The shortest time between two lines (s), the last one excepted.
    QUIET = 5.0

    def __init__(self, iterable: Any = None, total: int | None = None, initial: int = 0, desc: str = "",
                 unit: str = "it", **_ignored: Any) -> None:
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)
        self.iterable, self.total, self.n, self.desc, self.unit = iterable, total, initial, desc, unit
        self._postfix = ""
        self._start = self._last_time = time.monotonic()
        self._start_n = self._last_n = initial
        self._closed = False

    def __iter__(self) -> Iterator:
        for item in self.iterable:
            yield item
            self.update(1)
        self.close()

    def __enter__(self) -> "ProgressLines":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def set_postfix(self, values: dict | None = None, **kwargs: Any) -> None:
        self._postfix = ", ".join(f"{k} {v}" for k, v in {**(values or {}), **kwargs}.items())

    def set_postfix_str(self, text: str) -> None:
        self._postfix = text

    def update(self, n: int = 1) -> None:
        self.n += n
        now = time.monotonic()
        if now - self._last_time < self.QUIET:
            return
        step = self.STEP * self.total if self.total else math.inf
        if self.n - self._last_n >= step or now - self._last_time >= self.EVERY:
            self._write(now)

    def close(self) -> None:
        if not self._closed and self.n != self._last_n:
            self._write(time.monotonic())
        self._closed = True

    def _write(self, now: float) -> None:
        done = f"{self.n}/{self.total}" if self.total else f"{self.n}"
        share = f" ({100 * self.n / self.total:.0f}%)" if self.total else ""
        rate = (self.n - self._start_n) / (now - self._start) if now > self._start else 0.0
        parts = [f"{done} {self.unit}s{share}", f"{rate:.3g} {self.unit}/s"]
        parts += [self._postfix] if self._postfix else []
        logging.getLogger(__name__).info(f"{self.desc}: {', '.join(parts)}" if self.desc else ", ".join(parts))
        self._last_time, self._last_n = now, self.n


#: The signal that stopped the command (SIGINT for Ctrl-C, SIGTERM), for its exit status.
_stopped_by = {"signal": signal.SIGINT}


def _stop(signum: int, frame: Any) -> None:
    """SIGTERM's handler: stop as Ctrl-C does (a KeyboardInterrupt in the main thread); a second SIGTERM while the
    command keeps its work (writes its checkpoint) is ignored."""
    if _stopped_by["signal"] == signum:
        return
    _stopped_by["signal"] = signum
    raise KeyboardInterrupt


@contextmanager
def stop_signals() -> Iterator[None]:
    """A block in which SIGTERM stops the command as Ctrl-C does (every command that answers Ctrl-C by keeping
    its work then answers SIGTERM alike); the previous handler is restored after it. Outside the main thread,
    where no signal handler can be set, the block changes nothing."""
    _stopped_by["signal"] = signal.SIGINT
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupted_status() -> int:
    """The exit status of an interrupted command: 128 + the signal that stopped it (130 for Ctrl-C, 143 for
    SIGTERM)."""
    return 128 + int(_stopped_by["signal"])


def invoked_as() -> str:
    """How the program was started: ``python -m tracker`` or ``pose-tracker`` (for commands quoted back to the
    user as typed)."""
    spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    return "python -m tracker" if getattr(spec, "name", None) == "tracker.__main__" else PROG


def error_line(message: str) -> str:
    """The one form of every refusal on the command line: ``pose-tracker: error: MESSAGE``."""
    return f"{PROG}: error: {message}"
