"""Training clips read from mocap files: :func:`load_clips` (files, folders or patterns, retargeted and cached;
``tracker.load_clips``) and :func:`load_clip_specs` (an experiment's clips, each cut to its frame range).
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Iterable, Mapping, Sequence

from tracker.app.experiment_spec import ClipSpec
from tracker.core.errors import InputError

if TYPE_CHECKING:
    from data_tools.motion.retarget import RetargetResult


def load_clips(mocap: str | Path | Iterable[str | Path], skeletons: Iterable[str | Path] | None = None,
               fps: float | None = 60.0, joint_maps: Iterable[str | Path | Mapping | None] | str | Path | None = None,
               cache: str | Path | bool | None = True) -> list[RetargetResult]:
    """The mocap files that ``mocap`` names (a file, folder or glob pattern, or a list of them: a folder means
    every file a registered reader takes in it and below, in sorted order; docs/guide/training.md) retargeted
    at ``fps`` Hz, as :func:`tracker.load_clip` does each. ``skeletons`` and ``joint_maps``: one for all files or
    one per file (as :func:`tracker.train` takes them). ``cache``: the folder of converted clips, so that each
    file is retargeted once (True: the user's cache folder, ``$POSE_TRACKER_CACHE``; None or False: none)."""
    from data_tools.motion.load import load_training_clips
    return load_training_clips(mocap, skeletons, fps, joint_maps, cache=Path(cache) if isinstance(cache, (str, Path))
                               else cache)


def load_clip_specs(clips: Sequence[ClipSpec], fps: float,
                    skeletons: Sequence[str | Path] | None = None) -> list[RetargetResult]:
    """The retargeted training clips of an experiment's :class:`~tracker.app.experiment_spec.ClipSpec` entries
    (:func:`load_clips`, each with its joint map), each cut to its frame range (``skeletons``: one ASF for all
    AMC clips or one per clip; default the one beside each). A clip left with fewer than 3 frames is refused."""
    maps = [m.joint_map for m in clips]
    loaded = load_clips([m.path for m in clips], skeletons, fps,
                        None if all(j is None for j in maps) else [j or "none" for j in maps])
    cut = [slice(m.start, None if m.frames is None else m.start + m.frames) for m in clips]
    out = [replace(c, poses=c.poses[k], markers=c.markers[k], model_markers=c.model_markers[k])
           for c, k in zip(loaded, cut)]
    for c, m in zip(out, clips):
        if len(c.poses) < 3:
            raise InputError(f"training clip {m.path.name} has {len(c.poses)} frame(s) from start {m.start}")
    return out
