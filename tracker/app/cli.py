"""Command line: ``pose-tracker <command>`` (also ``python -m tracker <command>``; the contract: README,
"Commands").

:func:`main` reads the plugins a command line names, parses it (:mod:`tracker.app.parser`; each command's flags
in its module of :mod:`tracker.app.commands`) and runs the command's handler, which calls the public API. Every
bad input ends with a one-line reason on stderr, ``pose-tracker: error: ...``, and exit status 2. Informational
lines (what was read, chosen and written, timings, progress) go through :mod:`logging`
(:mod:`tracker.app.console`: ``--quiet``, ``--verbose``); what says how well a command's job went goes to stdout:
track's and demo's errors, compare's tables, train's fit, convert's retarget residual.
"""
from __future__ import annotations

import gc
import logging
import os
import sys
from typing import NoReturn, Sequence

from tracker.app.commands import command
from tracker.app.console import close_bars, configure_logging, error_line, interrupted_status, stop_signals, verbosity
from tracker.app.parser import parse_arguments
from tracker.app.plugins import import_plugin
from tracker.app.threads import set_threads
from tracker.core.errors import InputError

log = logging.getLogger(__name__)


def _plugins_from_argv(argv: list[str]) -> list[str]:
    """``--plugin`` values, read before the parser is built (plugins add choices and flags to it)."""
    found = []
    for i, a in enumerate(argv):
        if a == "--plugin" and i + 1 < len(argv):
            found.append(argv[i + 1])
        elif a.startswith("--plugin="):
            found.append(a.split("=", 1)[1])
    return found


def run() -> NoReturn:
    """The ``pose-tracker`` program: :func:`main` on the command line's arguments, then exit with its status.

    The objects left at exit are frozen first (:func:`gc.freeze`), so that the interpreter's final collections
    skip them: numba's compiled-code objects made every exit take 0.15-0.25 s longer. A reader that closes the
    output early (``pose-tracker corpus DIR --json | head``) ends the program quietly, as other shell tools do."""
    try:
        status = main()
        sys.stdout.flush()
    except BrokenPipeError:  # the rest of the output has nowhere to go: none of it is an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        status = 141  # 128 + SIGPIPE, as a shell reports a pipeline's writer stopped by the reader
    gc.freeze()
    sys.exit(status)


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command line (``argv``, default the process's arguments); returns the exit status. SIGTERM stops
    a command as Ctrl-C does (:func:`tracker.app.console.stop_signals`; exit status 143)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    configure_logging()  # INFO until the arguments say otherwise (a deprecated flag warns while they are parsed)
    with stop_signals():
        try:
            for spec in _plugins_from_argv(argv):
                import_plugin(spec)
            args = parse_arguments(argv)
            configure_logging(verbosity(args.quiet, args.verbose))
            args.argv = argv
            log.debug(f"arguments: {vars(args)}")
            if args.command != "compare":  # compare gives each worker its share instead
                set_threads(args.threads)
            return command(args.command).run(args)
        except InputError as exc:
            close_bars()  # the error is the last line: no bar drawn again below it
            print(error_line(str(exc)), file=sys.stderr)
            return 2
        except KeyboardInterrupt:  # Ctrl-C where a command has nothing to keep (those that do answer it themselves)
            close_bars()
            log.warning("interrupted; nothing was written that a rerun would not write again")
            return interrupted_status()
        except (MemoryError, RuntimeError) as exc:  # sizes within the checked ranges that this machine cannot hold
            if isinstance(exc, RuntimeError) and "can't allocate memory" not in str(exc):  # torch's allocator says so
                raise
            close_bars()
            reason = str(exc).splitlines()[0][:160] if str(exc) else "allocation failed"
            print(error_line(f"not enough memory for these settings ({reason}); choose smaller sizes"),
                  file=sys.stderr)
            return 2
