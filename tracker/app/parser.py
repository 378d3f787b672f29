"""The command line's arguments: the parser of ``pose-tracker`` (the contract: README, "Commands").

The program's own flags are declared here and each command's in its module (:mod:`tracker.app.commands`); the
flags of the priors and likelihoods come from the registries, for the prior (and likelihood) a command line
names: ``track --prior crbm --help`` shows the CRBM's options and no other prior's, and ``track --help`` lists
the priors with one line each. A flag of another plugin than the one named is refused in one line
(:func:`parse_arguments`).
"""
from __future__ import annotations

import argparse
import difflib
from typing import Sequence

from tracker.app.commands import command_modules
from tracker.app.commands.arguments import (UNNAMED_LIKELIHOOD, chosen, given_options,  # noqa: F401 (re-exported)
                                            option_flags, positive_int)
from tracker.app.console import PROG, error_line
from tracker.app.plugins import available_likelihoods, available_priors, likelihood_entry, prior_entry
from tracker.core.errors import InputError


class _Parser(argparse.ArgumentParser):
    """argparse with exit status 2 and a one-line message for usage errors, in the form of every other refusal
    (``pose-tracker: error: track: ...``, naming the command whose arguments were wrong)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        command = " ".join(self.prog.split()[1:])
        self.exit(2, error_line(f"{command}: {message}" if command else message) + "\n")


def _verbosity_flags(parser: argparse.ArgumentParser, default) -> None:
    """``--quiet`` and ``--verbose`` (one or the other), before the command or after it."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true", default=default,
                       help="show only warnings and errors: no progress bars or informational lines (results "
                            "still go to stdout)")
    group.add_argument("-v", "--verbose", action="store_true", default=default, help="show debug lines too")


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The parser; the prior and likelihood that ``argv`` names (``--prior``, ``--likelihood``) bring their own
    flags to ``train`` and ``track``."""
    from tracker import __version__

    p = _Parser(prog=PROG, description="3D human pose tracking with learned dynamical priors.")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    _verbosity_flags(p, False)
    p.add_argument("--plugin", action="append", default=[], metavar="MODULE_OR_FILE",
                   help="import a module (or .py file) that registers priors or likelihoods; repeatable")
    p.add_argument("--threads", type=positive_int, default=None,
                   help="threads for numpy/BLAS, OpenCV and torch (default: the cores available to the process)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    plugin_flag = argparse.ArgumentParser(add_help=False)  # --plugin is read before parsing; accepted anywhere
    plugin_flag.add_argument("--plugin", action="append", default=argparse.SUPPRESS, metavar="MODULE_OR_FILE",
                             help=argparse.SUPPRESS)
    _verbosity_flags(plugin_flag, argparse.SUPPRESS)  # also after the command: pose-tracker track ... --quiet
    sub.required = True
    for module in command_modules():
        module.add_parser(sub, [plugin_flag], argv)
    return p


def _refuse_foreign_flags(argv: Sequence[str]) -> None:
    """A flag of a prior or likelihood that the command line does not name is refused in one line."""
    if not argv or argv[0] not in ("train", "track"):
        return
    command = argv[0]
    prior, likelihood = chosen(argv, "--prior"), chosen(argv, "--likelihood") or UNNAMED_LIKELIHOOD
    owners: dict[str, list[str]] = {}
    for name in available_priors():
        entry = prior_entry(name)
        for o in (entry.train_options if command == "train" else entry.options):
            for flag in option_flags(o):
                owners.setdefault(flag, []).append(f"prior {name}")
    if command == "track":
        for name in available_likelihoods():
            for o in likelihood_entry(name).options:
                for flag in option_flags(o):
                    owners.setdefault(flag, []).append(f"likelihood {name}")
    mine = {f"prior {prior}", f"likelihood {likelihood}"}
    for token in argv[1:]:
        flag = token.split("=", 1)[0]
        if flag in owners and not mine & set(owners[flag]):
            if prior is None:
                raise InputError(f"{flag} is an option of {', '.join(owners[flag])}: name the prior with --prior")
            raise InputError(f"{flag} does not apply to prior {prior}"
                             + ("" if command == "train" else f" or likelihood {likelihood}"))


def parse_arguments(argv: Sequence[str]) -> argparse.Namespace:
    """The parsed command line (plugins already imported); usage errors exit with status 2 and one line."""
    argv = list(argv)
    command = next((i for i, a in enumerate(argv) if a in ("train", "track")), None)
    if command is not None:
        _refuse_foreign_flags(argv[command:])
    parser = build_parser(argv)
    args, extra = parser.parse_known_args(argv)
    if extra:  # what argparse would refuse, with the nearest flag of the command named (a typo, say)
        command_parser = _command_parser(parser, getattr(args, "command", None))
        command_parser.error(f"unrecognized arguments: {' '.join(extra)}{_suggestion(extra, command_parser)}")
    return args


def _command_parser(parser: argparse.ArgumentParser, command: str | None) -> argparse.ArgumentParser:
    """The parser of ``command`` (the top-level one when there is none)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and command in action.choices:
            return action.choices[command]
    return parser


def _suggestion(extra: Sequence[str], parser: argparse.ArgumentParser) -> str:
    """`` (did you mean --particles?)`` for the first unrecognised flag that is close to one ``parser`` takes,
    else nothing."""
    flags = [f for f in parser._option_string_actions if f.startswith("--")]
    for token in extra:
        if token.startswith("--"):
            close = difflib.get_close_matches(token.split("=", 1)[0], flags, n=1, cutoff=0.75)
            if close:
                return f" (did you mean {close[0]}?)"
    return ""
