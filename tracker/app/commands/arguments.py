"""What the commands' parsers share: argument types with their ranges, the flags of a plugin's options, the
catalogue of plugins a command's help lists, and deprecated flag spellings.

Each type converts one command-line value and refuses a bad one in argparse's form (``expected an integer, got
'x'``; ``must be at least 1, got 0``); the commands' handlers receive checked values.
"""
from __future__ import annotations

import argparse
import logging
import textwrap
from typing import Sequence

import numpy as np

from data_tools.io.checks import MAX_FPS, MAX_MM_PER_UNIT, MIN_FPS, MIN_MM_PER_UNIT
from tracker.app.plugins import likelihood_entry, prior_entry
from tracker.app.schema import KEYPOINT_LIKELIHOOD, argument_type, setting
from tracker.core.errors import InputError
from tracker.engine.registry import Option

log = logging.getLogger(__name__)


def number_type(kind: type, minimum: float, strict: bool, maximum: float | None = None, strict_max: bool = False):
    """An argparse type: ``kind`` (int or float), finite, above (``strict``) or at least ``minimum``, and below
    (``strict_max``) or at most ``maximum`` when given; the message gives the range."""
    noun = "an integer" if kind is int else "a number"
    bound = f"greater than {minimum:g}" if strict else f"at least {minimum:g}"
    if maximum is not None:
        bound += f" and {'less than' if strict_max else 'at most'} {maximum if kind is int else format(maximum, 'g')}"

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {noun}, got {text!r}") from None
        if (kind is float and not np.isfinite(value)) or value < minimum or (strict and value == minimum) \
                or (maximum is not None and (value > maximum or (strict_max and value == maximum))):
            raise argparse.ArgumentTypeError(f"must be {bound}, got {text}")
        return value

    return parse


positive_float = number_type(float, 0.0, strict=True)
non_negative_float = number_type(float, 0.0, strict=False)
positive_int = number_type(int, 1, strict=False)
non_negative_int = number_type(int, 0, strict=False)
#: Plausible ranges of the command-line values that size arrays or scale arithmetic (the API checks its own).
seed_type = argument_type(setting("seed"))
fps_type = number_type(float, MIN_FPS, strict=False, maximum=MAX_FPS)
length_unit_type = number_type(float, MIN_MM_PER_UNIT, strict=False, maximum=MAX_MM_PER_UNIT)
JOINT_MAP_HELP = ("JSON or TOML file naming the file's joint for each body point (pelvis = \"Hips\", ...), for "
                  "skeletons whose names are not recognised (docs/guide/motion_capture.md)")
#: Whose options a ``track`` command line takes when it names no likelihood: the default likelihood is chosen by
#: the sequence (:func:`tracker.app.api.default_likelihood`), and these are the options of both choices.
UNNAMED_LIKELIHOOD = KEYPOINT_LIKELIHOOD


class DeprecatedAlias(argparse.Action):
    """An old spelling of a flag, kept for one version: it sets the new flag's value and logs a warning."""

    def __init__(self, option_strings, dest, new_flag: str, why: str = "", **kwargs):
        super().__init__(option_strings, dest, **kwargs)
        self.new_flag, self.why = new_flag, why

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        command = " ".join(parser.prog.split()[1:])
        log.warning(f"{command} {option_string} is deprecated and will be removed: use {self.new_flag}"
                    f"{self.why}")
        setattr(namespace, self.dest, values)


def option_type(option: Option):
    """The argparse type of a plugin option: the conversion only (ranges are checked per plugin), its message in
    argparse's form (``argument --switch: must be at least 0 and at most 0.5, got '0.9'``)."""
    def parse(text: str):
        try:
            return option.parse(text, option.flag)
        except InputError as exc:
            reason = exc.reason.removeprefix(f"{option.flag}: ").removeprefix(f"{option.name} ")
            raise argparse.ArgumentTypeError(reason) from None
    return parse if option.type is not str else str


def wrapped(text: str) -> str:
    """``text`` filled to 79 columns (a description whose formatting is kept as written)."""
    return textwrap.fill(text, 79)


def catalogue(kind: str, names: Sequence[str], command: str, flag: str = "--prior") -> str:
    """One line per registered plugin, and how to see one's own options."""
    summaries = {n: (prior_entry(n) if flag == "--prior" else likelihood_entry(n)).summary for n in names}
    width = max(len(n) for n in names) + 2
    lines = [f"{kind} ({command} {flag} NAME --help shows one's own options):"]
    for name, summary in summaries.items():
        body = textwrap.wrap(summary or "", 79 - width - 2) or [""]
        lines.append(f"  {name:<{width}}{body[0]}")
        lines += [" " * (width + 2) + more for more in body[1:]]
    return "\n".join(lines)


def chosen(argv: Sequence[str], flag: str) -> str | None:
    """The value ``argv`` gives ``flag`` (``--prior crbm`` or ``--prior=crbm``), or None."""
    argv = list(argv)
    for i, a in enumerate(argv):
        if a == flag and i + 1 < len(argv):
            return argv[i + 1]
        if a.startswith(flag + "="):
            return a.split("=", 1)[1]
    return None


def option_flags(option: Option) -> list[str]:
    """The flags of a plugin option: ``--name``, and ``--no-name`` for a bool."""
    return [option.flag] + (["--no-" + option.flag[2:]] if option.type is bool else [])


def check_clashes(parser: argparse.ArgumentParser, declared: dict[str, tuple[Option, ...]]) -> None:
    """Refuse a plugin option whose flag the command already has."""
    taken = set(parser._option_string_actions)  # the command's own flags
    for options in declared.values():
        for o in options:
            if o.flag in taken:
                raise InputError(f"plugin option {o.flag} clashes with a flag of the {parser.prog.split()[-1]} "
                                 "command; rename the option")


def plugin_group(parser: argparse.ArgumentParser, title: str, options: Sequence[Option]) -> None:
    """The options of one plugin as a group of flags (default None: "not given"; the plugin applies its own)."""
    group = parser.add_argument_group(title)
    for o in options:
        if o.type is bool:  # --flag and --no-flag: a setting that is on by default can be turned off
            group.add_argument(o.flag, dest=o.name, action=argparse.BooleanOptionalAction, default=None,
                               help=o.described())
        else:
            group.add_argument(o.flag, dest=o.name, type=option_type(o), default=None, metavar=o.name.upper(),
                               help=o.described())


def given_options(args: argparse.Namespace, declared: Sequence[Option]) -> dict:
    """The options of one plugin set on the command line (or in a resumed run's saved arguments)."""
    return {o.name: getattr(args, o.name) for o in declared if getattr(args, o.name, None) is not None}
