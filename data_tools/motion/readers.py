"""Mocap readers found by file suffix: the extension point for motion-capture formats.

A reader is a function ``read(path, options) -> MocapClip`` registered for one suffix (``.amc``, ``.bvh``, ...)
with a name. :mod:`data_tools.motion.load` registers the built-in ones (ASF/AMC and BVH) and picks the reader of
a file by its suffix (:func:`~data_tools.motion.load.reader_for`, :func:`~data_tools.motion.load.load_mocap`). A
plugin adds a format with :func:`register_mocap_reader` (in a module loaded with ``--plugin`` or through the ``pose_tracker.plugins`` entry-point group, like a prior or a likelihood).

Whatever the file's convention, a reader returns positions in millimetres with z up, the file's frame rate
and its point names (:class:`~data_tools.motion.mocap.MocapClip`), and refuses a bad file with one
:class:`~tracker.core.errors.InputError` naming the file. :class:`tracker.testing.MocapReaderContract` checks
a reader against that contract. This module holds only the table.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Mapping

from tracker.engine.registry import Registry

if TYPE_CHECKING:
    from data_tools.motion.mocap import MocapClip


@dataclass(frozen=True)
class ReadOptions:
    """What a user may say about a mocap file beyond its path.

    ``skeleton``: a separate skeleton file (formats whose motion file lacks one, e.g. ASF for AMC; refused for
    the others); ``mm_per_unit``: the file's length unit in mm (None: the reader infers or knows it);
    ``source_fps``: the capture rate (Hz) for formats that do not record it; ``joint_map``: a JSON or TOML
    file, or a mapping, naming the file's points for the body's
    (:func:`~data_tools.motion.skeleton_points.read_joint_map`), None for names of a recognised convention.
    """

    skeleton: Path | None = None
    mm_per_unit: float | None = None
    source_fps: float | None = None
    joint_map: str | Path | Mapping | None = None


@dataclass(frozen=True)
class MocapReader:
    """A registered reader: its ``suffix`` (lower case, with the dot), ``name`` (the format, in messages),
    ``read(path, options) -> MocapClip``, a one-line ``summary``, and whether the format takes a separate
    ``skeleton`` file (and which suffix that file has, to say so in messages)."""

    suffix: str
    name: str
    read: Callable[[Path, ReadOptions], "MocapClip"]
    summary: str = ""
    skeleton: str | None = None

    def described(self) -> str:
        """The reader in a listing: ``.amc (ASF/AMC, with its .asf skeleton)``."""
        with_skeleton = f", with its {self.skeleton} skeleton" if self.skeleton else ""
        return f"{self.suffix} ({self.name}{with_skeleton})"


#: The registered readers by suffix (the engine's :class:`~tracker.engine.registry.Registry`, keyed by suffix).
READERS: Registry[MocapReader] = Registry(
    "mocap reader", key="suffix", function="read",
    taken="mocap files {key} are already read by {old} ({entry.name}); {new} cannot take the suffix")


def register_mocap_reader(suffix: str, name: str, *, summary: str = "", skeleton: str | None = None):
    """Decorator registering ``read(path: Path, options: ReadOptions) -> MocapClip`` for files ending in
    ``suffix`` (e.g. ``".c3d"``; case is ignored). ``skeleton`` is the suffix of the separate skeleton file the
    format needs (None: the file carries its own). A suffix registers once; re-registering the same function
    (a module imported again) is fine."""
    key = suffix.lower()
    if not key.startswith(".") or len(key) < 2 or "." in key[1:] or "/" in key:
        raise ValueError(f"a mocap reader's suffix is one dot and a name, e.g. '.bvh'; got {suffix!r}")

    def decorate(read):
        READERS.add(MocapReader(key, name, read, summary, skeleton))
        return read
    return decorate
