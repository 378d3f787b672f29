"""The settings of a video import, declared once: ``pose-tracker import-video``'s flags, the keywords of
:func:`data_tools.vision.video.import_videos` (and ``capture``'s ``downscale``, whose default differs) derive from
them. This module imports no video code, so the command line's help reads it cheaply."""
from __future__ import annotations

from tracker.engine.registry import Option

__all__ = ["IMPORT_OPTIONS", "import_option"]

IMPORT_OPTIONS: tuple[Option, ...] = (
    Option("downscale", float, 1.0, "shrink every frame by F, the intrinsics scaled to match", minimum=1.0,
           maximum=64.0),
    Option("frames", str, None, "video frames A to B-1, as A:B (required when the videos' frame counts differ)"),
)


def import_option(name: str) -> Option:
    """The declared import setting ``name``."""
    return next(o for o in IMPORT_OPTIONS if o.name == name)
