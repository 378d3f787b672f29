"""One entry point for reading any supported mocap file into a :class:`~data_tools.mocap.MocapClip`: the
built-in readers (ASF/AMC, BVH) registered by suffix (:mod:`data_tools.readers`), the reader of a file found by
its suffix, and training clips read and retargeted."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

from data_tools.asf_amc import CMU_FPS, asf_amc_clip
from data_tools.bvh import bvh_clip
from data_tools.mocap import MocapClip
from data_tools.readers import READERS, MocapReader, ReadOptions, register_mocap_reader
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


def apply_joint_map(clip: MocapClip, joint_map: str | Path | Mapping | None) -> MocapClip:
    """``clip`` with its body points planned from ``joint_map`` (a JSON or TOML file, or a mapping; None: the
    names' recognised convention, planned when first asked), and the plan's notes added to the clip's: for a
    reader whose format needs no joint map to read the file itself."""
    if joint_map is not None:
        map_source = None if isinstance(joint_map, Mapping) else joint_map
        clip.plan = plan_points(clip.point_names, clip.style, read_joint_map(joint_map), clip.path, map_source)
    clip.notes += clip.point_plan().notes
    return clip


@register_mocap_reader(".amc", "ASF/AMC", skeleton=".asf",
                       summary="Acclaim motion (CMU database) on its ASF skeleton; the rate is not in the file "
                               f"(default {CMU_FPS:g} Hz)")
def read_asf_amc(path: Path, options: ReadOptions) -> MocapClip:
    """An AMC motion on its ASF skeleton (``options.skeleton``, else :func:`find_skeleton`), at
    ``options.source_fps`` (default :data:`~data_tools.asf_amc.CMU_FPS`)."""
    skeleton = options.skeleton if options.skeleton is not None else find_skeleton(path)
    fps = CMU_FPS if options.source_fps is None else options.source_fps
    return apply_joint_map(asf_amc_clip(skeleton, path, fps), options.joint_map)


@register_mocap_reader(".bvh", "BVH", summary="Biovision hierarchy: skeleton, rate and motion in one file")
def read_bvh_file(path: Path, options: ReadOptions) -> MocapClip:
    """A BVH file at its own rate; its length unit ``options.mm_per_unit`` or inferred
    (:func:`~data_tools.bvh.bvh_clip`)."""
    return bvh_clip(path, options.mm_per_unit, options.joint_map)


def registered_readers() -> list[MocapReader]:
    """The registered mocap readers (the built-in ones first), in the order they registered."""
    return list(READERS.values())


def reader_for(path: str | Path) -> MocapReader:
    """The reader of ``path``'s suffix (case ignored); an :class:`InputError` naming the file and listing the
    registered readers when none reads it."""
    path = Path(path)
    suffix = path.suffix.lower()
    reader = READERS.get(suffix)
    if reader is None:
        known = ", ".join(r.described() for r in READERS.values())
        raise InputError(f"unknown mocap format {repr(suffix) if suffix else '(no suffix)'}: the registered "
                         f"readers take {known}", path)
    return reader


def load_mocap(path: str | Path, skeleton: str | Path | None = None, mm_per_unit: float | None = None,
               source_fps: float | None = None, joint_map: str | Path | Mapping | None = None) -> MocapClip:
    """Read a mocap file with the reader registered for its suffix (:func:`registered_readers`: AMC with its
    ASF, BVH, and those of plugins) as joint positions in mm, z up.

    ``skeleton`` is the separate skeleton file of formats that need one (an AMC's ASF; found beside the file
    when None), refused for the others. ``mm_per_unit`` is the file's length unit where the format leaves it
    open (BVH; inferred when None). ``source_fps`` is the capture rate of formats that do not record it (AMC;
    None: the CMU database's 120 Hz). ``joint_map`` (a JSON or TOML file, or a mapping) names the file's points
    for the body's (:func:`~data_tools.skeleton_points.read_joint_map`); without one the names must follow a
    recognised convention (:mod:`data_tools.joint_names`). Points the file lacks and that can be derived are,
    and the clip's ``notes`` say so.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path)
    reader = reader_for(path)
    if skeleton and reader.skeleton is None:
        takes = [r.name for r in READERS.values() if r.skeleton is not None]
        raise InputError(f"a {reader.name} file carries its own skeleton; --skeleton applies to "
                         f"{' and '.join(takes) or 'no'} files only", path)
    options = ReadOptions(Path(skeleton) if skeleton else None, mm_per_unit, source_fps, joint_map)
    return reader.read(path, options)


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
        reader = READERS.get(f.suffix.lower())  # (an unknown suffix is refused by load_mocap, after a missing file)
        if skel is not None and reader is not None and reader.skeleton is None:
            skel = None
        results.append(retarget(load_mocap(f, skel, joint_map=maps[i]), fps=fps))
    return results
