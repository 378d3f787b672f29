"""The commands of ``pose-tracker``, one module each: its flags and its handler side by side.

A command module defines ``NAME`` (the command, ``import-video``), ``add_parser(sub, parents, argv)`` (adds its
parser to the program's commands and returns it; ``argv`` is the whole command line, for flags that depend on
the prior it names) and ``run(args) -> int`` (parses nothing: calls the API with the checked values and reports
what it did; the exit status). :data:`COMMANDS` lists the modules in the order ``pose-tracker --help`` shows
them (a name of this package's, or a module's full dotted path): a new command is its module plus its line
there. Modules import what their ``run`` needs inside it, so that building the parser (every command line,
``--help``) stays cheap.
"""
from __future__ import annotations

import importlib
from types import ModuleType

#: The command modules, in the order the program's help lists them.
COMMANDS: tuple[str, ...] = (
    "convert", "corpus", "synth", "show", "train", "track", "compare", "fetch", "demo",
    "import_video", "silhouettes", "keypoints", "initialise", "capture", "export", "compare_trc", "info",
)


def _module(entry: str) -> ModuleType:
    return importlib.import_module(entry if "." in entry else f"{__name__}.{entry}")


def command_modules() -> list[ModuleType]:
    """The command modules of :data:`COMMANDS`, imported, in order."""
    return [_module(entry) for entry in COMMANDS]


def command(name: str) -> ModuleType:
    """The module of the command ``name`` (as typed: ``import-video``)."""
    found = next((m for m in command_modules() if m.NAME == name), None)
    if found is None:
        raise KeyError(name)
    return found
