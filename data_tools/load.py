"""One entry point for reading any supported mocap file into a :class:`~data_tools.mocap.MocapClip`."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

from data_tools.asf_amc import CMU_FPS, asf_amc_clip
from data_tools.bvh import bvh_clip
from data_tools.mocap import MocapClip
from data_tools.skeleton_points import plan_points, read_joint_map
from tracker.core.errors import InputError


def find_skeleton(amc: Path) -> Path:
    """The ASF for an AMC when none is given: ``<subject>.asf`` beside it (CMU naming), else the only ASF there."""
    subject = amc.stem.split("_")[0]
    candidate = amc.with_name(subject + ".asf")
    if candidate.exists():
        return candidate
    asfs = sorted(amc.parent.glob("*.asf"))
    if len(asfs) == 1:
        return asfs[0]
    raise InputError("AMC motion needs its ASF skeleton: pass --skeleton (none or several .asf files beside it)",
                     amc)


def load_mocap(path: str | Path, skeleton: str | Path | None = None, mm_per_unit: float | None = None,
               source_fps: float = CMU_FPS, joint_map: str | Path | Mapping | None = None) -> MocapClip:
    """Read an AMC (with its ASF) or a BVH file as joint positions in mm, z up.

    ``mm_per_unit`` applies to BVH only (inferred when None). ``source_fps`` is
    the AMC's capture rate, which AMC files do not record (CMU: 120 Hz).
    ``joint_map`` (a JSON or TOML file, or a mapping) names the file's points
    for the body's (:func:`~data_tools.skeleton_points.read_joint_map`);
    without one the names must follow a recognised convention
    (:mod:`data_tools.joint_names`). Points the file lacks and that can be
    derived are, and the clip's ``notes`` say so.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path)
    suffix = path.suffix.lower()
    if suffix == ".amc":
        clip = asf_amc_clip(Path(skeleton) if skeleton else find_skeleton(path), path, source_fps)
        if joint_map is not None:
            map_source = None if isinstance(joint_map, Mapping) else joint_map
            clip.plan = plan_points(clip.point_names, clip.style, read_joint_map(joint_map), clip.path, map_source)
        clip.notes += clip.point_plan().notes
        return clip
    if suffix == ".bvh":
        if skeleton:
            raise InputError("a BVH file carries its own skeleton; --skeleton applies to AMC files only", path)
        return bvh_clip(path, mm_per_unit, joint_map)
    raise InputError(f"unknown mocap format {suffix!r}: expected .amc (with an .asf skeleton) or .bvh", path)


def per_clip(values, n: int, what: str) -> list:
    """``values`` (None, one for all ``n`` clips, or one per clip) as a list of ``n``; ``"none"`` is None."""
    values = [] if values is None else ([values] if isinstance(values, (str, Path, Mapping)) else list(values))
    if values and len(values) not in (1, n):
        raise InputError(f"give one {what} for all clips or one per clip ({n}), got {len(values)}")
    out = [values[0] if len(values) == 1 else values[i] for i in range(n)] if values else [None] * n
    return [None if isinstance(v, str) and v.lower() == "none" else v for v in out]


def load_training_clips(files, skeletons=None, fps: float | None = 60.0, joint_maps=None) -> list:
    """Retargeted clips (:class:`~data_tools.retarget.RetargetResult`) of mocap files, each resampled to
    ``fps`` Hz (None: each at its own rate).

    ``skeletons`` is ``None`` (each AMC finds ``<subject>.asf`` beside it), one ASF for every AMC, or one per
    file (BVH files carry their own and ignore theirs). ``joint_maps`` likewise: None, one for every clip, or
    one per clip (``"none"`` for a clip whose names are recognised). Clips of different subjects are each
    retargeted with their own skeleton and keep their own lengths.
    """
    from data_tools.retarget import retarget

    files = [Path(f) for f in files]
    if not files:
        raise InputError("no training clips given")
    skeletons = list(skeletons or [])
    if skeletons and len(skeletons) not in (1, len(files)):
        raise InputError(f"give one skeleton for all clips or one per clip ({len(files)}), got {len(skeletons)}")
    maps = per_clip(joint_maps, len(files), "joint map")
    results = []
    for i, f in enumerate(files):
        skel = None if not skeletons else skeletons[0 if len(skeletons) == 1 else i]
        if skel is not None and f.suffix.lower() != ".amc":
            skel = None
        results.append(retarget(load_mocap(f, skel, joint_map=maps[i]), fps=fps))
    return results
