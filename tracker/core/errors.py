"""The one exception type for bad input.

Every reader and every public entry point that can be handed bad data raises
:class:`InputError` with a message that names the file (and line, where there
is one) and the problem. The command line turns it into a one-line message on
stderr and exit status 2.
"""
from __future__ import annotations

from os import PathLike


class InputError(ValueError):
    """Bad input: a malformed file, an impossible value, a shape mismatch."""

    def __init__(self, message: str, path: str | PathLike | None = None, line: int | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        self.reason = message
        where = ""
        if self.path is not None:
            where = f"{self.path}:{line}: " if line is not None else f"{self.path}: "
        super().__init__(where + message)
