"""How the command line talks to its user: the program's name, log lines and progress bars on stderr, and the one
form of every refusal.

The packages log through the standard :mod:`logging` module, one logger per module (``logging.getLogger(__name__)``),
and never configure it: a program that imports them decides what is shown. The command line does so once
(:func:`configure_logging`): informational lines (what was read, what was chosen, timings, summaries) at INFO,
shown by default; ``--quiet`` shows warnings only, ``--verbose`` debug lines too. What says how well a command's
job went is its result and goes to stdout, apart from the log: ``track``'s and ``demo``'s errors, ``compare``'s
tables, ``train``'s fit, ``convert``'s retarget residual. Progress bars count as informational: they show exactly
when INFO lines do (:func:`progress_bar`).
"""
from __future__ import annotations

import logging
import sys
from typing import Any

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


def progress_bar(iterable: Any = None, **options) -> Any:
    """A ``tqdm`` bar (on stderr) that is drawn when :func:`shows_progress` and is silent otherwise."""
    from tqdm import tqdm

    return tqdm(iterable, disable=not shows_progress(), **options)


def error_line(message: str) -> str:
    """The one form of every refusal on the command line: ``pose-tracker: error: MESSAGE``."""
    return f"{PROG}: error: {message}"
