"""One entry point for reading any supported mocap file into a :class:`~data_tools.mocap.MocapClip`."""
from __future__ import annotations

from pathlib import Path

from data_tools.asf_amc import CMU_FPS, asf_amc_clip
from data_tools.bvh import bvh_clip
from data_tools.mocap import MocapClip
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
               source_fps: float = CMU_FPS) -> MocapClip:
    """Read an AMC (with its ASF) or a BVH file as joint positions in mm, z up.

    ``mm_per_unit`` applies to BVH only (inferred when None). ``source_fps`` is
    the AMC's capture rate, which AMC files do not record (CMU: 120 Hz).
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path)
    suffix = path.suffix.lower()
    if suffix == ".amc":
        return asf_amc_clip(Path(skeleton) if skeleton else find_skeleton(path), path, source_fps)
    if suffix == ".bvh":
        if skeleton:
            raise InputError("a BVH file carries its own skeleton; --skeleton applies to AMC files only", path)
        return bvh_clip(path, mm_per_unit)
    raise InputError(f"unknown mocap format {suffix!r}: expected .amc (with an .asf skeleton) or .bvh", path)


def load_training_clips(files, skeletons=None, fps: float = 60.0) -> list:
    """Retargeted clips (:class:`~data_tools.retarget.RetargetResult`) of mocap files at ``fps`` Hz.

    ``skeletons`` is ``None`` (each AMC finds ``<subject>.asf`` beside it), one ASF for every AMC, or one per
    file (BVH files carry their own and ignore theirs). Clips of different subjects are each retargeted with
    their own skeleton and keep their own lengths.
    """
    from data_tools.retarget import retarget

    files = [Path(f) for f in files]
    if not files:
        raise InputError("no training clips given")
    skeletons = list(skeletons or [])
    if skeletons and len(skeletons) not in (1, len(files)):
        raise InputError(f"give one skeleton for all clips or one per clip ({len(files)}), got {len(skeletons)}")
    results = []
    for i, f in enumerate(files):
        skel = None if not skeletons else skeletons[0 if len(skeletons) == 1 else i]
        if skel is not None and f.suffix.lower() != ".amc":
            skel = None
        results.append(retarget(load_mocap(f, skel), fps=fps))
    return results
