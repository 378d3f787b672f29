"""The command-line reference (``docs/reference/cli.md``), written from the parsers so that it cannot drift.

    python -m tracker.app.cli_reference > docs/reference/cli.md

Each command's ``--help``, then the options each registered prior brings to ``track`` and ``train`` and the
options of each likelihood, exactly as ``pose-tracker track --prior NAME --help`` prints them. The text is
formatted at a fixed width, so it is the same on every terminal.
"""
from __future__ import annotations

import argparse
import os
from collections.abc import Iterator, Sequence

from tracker.app.api import available_likelihoods, available_priors, prior_entry
from tracker.app.commands import command_modules
from tracker.app.parser import build_parser

#: Columns the help is formatted to (argparse reads ``COLUMNS``).
WIDTH = 100


def _subparser(argv: Sequence[str], command: str) -> argparse.ArgumentParser:
    parser = build_parser(argv)
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices[command]


def _group_help(parser: argparse.ArgumentParser, title_start: str) -> str:
    """One argument group of a parser (a plugin's options), formatted as ``--help`` shows it."""
    group = next(g for g in parser._action_groups if g.title and g.title.startswith(title_start))
    formatter = parser._get_formatter()
    formatter.start_section(group.title)
    formatter.add_arguments(group._group_actions)
    formatter.end_section()
    return formatter.format_help().strip("\n")


def _block(text: str) -> str:
    return "```\n" + text.rstrip() + "\n```\n"


def sections() -> Iterator[str]:
    """The reference's Markdown, one section at a time."""
    yield ("# Command-line reference\n\n"
           "Generated from the parsers by `python -m tracker.app.cli_reference`; a test checks that it matches "
           "them. `pose-tracker` and `python -m tracker` are the same command. Plugins loaded with `--plugin` "
           "add their priors, likelihoods and options to `track` and `train`.\n")
    yield "## pose-tracker\n\n" + _block(build_parser([]).format_help())
    for command in (module.NAME for module in command_modules()):
        yield f"## {command}\n\n" + _block(_subparser([command], command).format_help())
    yield ("## Options of each prior\n\n"
           "`track --prior NAME` accepts the options of that prior (and `train --prior NAME` its training "
           "options); an option of another prior is refused. Unset options take the prior's own default, "
           "shown in brackets.\n")
    for name in available_priors():
        entry = prior_entry(name)
        parts = [f"### {name}\n\n{entry.summary}\n"]
        if entry.options:
            parts.append(_block(_group_help(_subparser(["track", "--prior", name], "track"), "options of the")))
        if entry.train is not None and entry.train_options:
            parts.append(_block(_group_help(_subparser(["train", "--prior", name], "train"),
                                            "training options of the")))
        yield "\n".join(parts)
    yield "## Options of each likelihood\n"
    for name in available_likelihoods():
        track = _subparser(["track", "--likelihood", name], "track")
        yield f"### {name}\n\n" + _block(_group_help(track, f"options of the {name} likelihood"))


def reference() -> str:
    """The whole reference at :data:`WIDTH` columns."""
    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(WIDTH)
    try:
        return "\n".join(sections())
    finally:
        if saved is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = saved


if __name__ == "__main__":
    print(reference(), end="")
