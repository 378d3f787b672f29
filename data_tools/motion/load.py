"""One entry point for reading any supported mocap file into a :class:`~data_tools.motion.mocap.MocapClip`: the
built-in readers (ASF/AMC, BVH) registered by suffix (:mod:`data_tools.motion.readers`), the reader of a file found by
its suffix, the mocap files that folders and glob patterns name (:func:`expand_mocap`), and training clips read
and retargeted through the cache of converted clips (:mod:`data_tools.motion.cache`)."""
from __future__ import annotations

import glob
from pathlib import Path
from typing import Iterable, Mapping

from data_tools.motion.asf_amc import CMU_FPS, asf_amc_clip
from data_tools.motion.bvh import bvh_clip
from data_tools.motion.mocap import MocapClip
from data_tools.motion.readers import READERS, MocapReader, ReadOptions, register_mocap_reader
from data_tools.motion.skeleton_points import plan_points, read_joint_map
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
    ``options.source_fps`` (default :data:`~data_tools.motion.asf_amc.CMU_FPS`)."""
    skeleton = options.skeleton if options.skeleton is not None else find_skeleton(path)
    fps = CMU_FPS if options.source_fps is None else options.source_fps
    return apply_joint_map(asf_amc_clip(skeleton, path, fps), options.joint_map)


@register_mocap_reader(".bvh", "BVH", summary="Biovision hierarchy: skeleton, rate and motion in one file")
def read_bvh_file(path: Path, options: ReadOptions) -> MocapClip:
    """A BVH file at its own rate; its length unit ``options.mm_per_unit`` or inferred
    (:func:`~data_tools.motion.bvh.bvh_clip`)."""
    return bvh_clip(path, options.mm_per_unit, options.joint_map)


def registered_readers() -> list[MocapReader]:
    """The registered mocap readers (the built-in ones first), in the order they registered."""
    return list(READERS.values())


def reader_for(path: str | Path) -> MocapReader:
    """The reader of ``path``'s suffix (case ignored); an :class:`InputError` naming the file and listing the
    registered readers when none reads it."""
    path = Path(path)
    suffix = path.suffix.lower()
    reader = READERS.find(suffix)
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
    for the body's (:func:`~data_tools.motion.skeleton_points.read_joint_map`); without one the names must follow a
    recognised convention (:mod:`data_tools.motion.joint_names`). Points the file lacks and that can be derived are,
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


#: Characters that make an item a glob pattern.
GLOB_CHARS = set("*?[")


def _readable(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in {r.suffix for r in registered_readers()}


def _takes() -> str:
    return ", ".join(r.suffix for r in registered_readers())


def _order(path: Path) -> tuple[str, ...]:
    """The sort key of a folder's or a pattern's files: folder by folder, then the name, characters compared by
    code point (case counts, on every system)."""
    return path.parts


def is_pattern(item: str | Path) -> bool:
    """Whether ``item`` is a glob pattern (holds ``*``, ``?`` or ``[``) rather than a path."""
    return bool(GLOB_CHARS & set(str(item)))


def expand_mocap(items: str | Path | Iterable[str | Path], base: Path | None = None) -> list[Path]:
    """The mocap files that ``items`` name, in order, each once: a file as it is (whatever its suffix: a file the
    user names is read or refused by name); a folder, every file in it and its subfolders (recursively) that a
    registered reader takes; a glob pattern (``*``, ``?``, ``[...]``; ``**`` crosses folders), its matches that
    a registered reader takes (an ``.asf`` is no clip: it is found beside its motion files). A folder's or a
    pattern's files come in sorted order of their paths (the same on every machine); a file named twice is kept
    once. Relative items are relative to ``base`` (None: the working folder). A missing file or folder, or a
    folder or pattern without mocap files, is an :class:`InputError` naming it."""
    items = [items] if isinstance(items, (str, Path)) else list(items)
    out: list[Path] = []
    for item in items:
        text = str(item)
        path = Path(text).expanduser()
        if base is not None and not path.is_absolute():
            path = base / path
        if is_pattern(text) and not path.exists():
            found = sorted((Path(p) for p in glob.glob(str(path), recursive=True)), key=_order)
            files = [p for p in found if _readable(p)]
            if not files:
                raise InputError(f"the pattern matches no mocap file ({_takes()})" if not found else
                                 f"the pattern matches {len(found)} path(s) but no mocap file ({_takes()})", text)
        elif path.is_dir():
            files = sorted((p for p in path.rglob("*") if _readable(p)), key=_order)
            if not files:
                raise InputError(f"the folder holds no mocap file ({_takes()}), in it or below", path)
        elif path.exists():
            files = [path]
        else:
            raise InputError("no such file or folder", path)
        out.extend(files)
    return list(dict.fromkeys(out))


def per_clip(values, n: int, what: str) -> list:
    """``values`` (None, one for all ``n`` clips, or one per clip) as a list of ``n``; ``"none"`` is None."""
    values = [] if values is None else ([values] if isinstance(values, (str, Path, Mapping)) else list(values))
    if values and len(values) not in (1, n):
        raise InputError(f"give one {what} for all clips or one per clip ({n}), got {len(values)}")
    out = [values[0] if len(values) == 1 else values[i] for i in range(n)] if values else [None] * n
    return [None if isinstance(v, str) and v.lower() == "none" else v for v in out]


def load_training_clips(files, skeletons=None, fps: float | None = 60.0, joint_maps=None,
                        cache: Path | None | bool = True) -> list:
    """Retargeted clips (:class:`~data_tools.motion.retarget.RetargetResult`) of mocap files, each resampled to
    ``fps`` Hz (None: each at its own rate).

    ``files`` are files, folders and glob patterns (:func:`expand_mocap`: a folder means
    every file a registered reader takes in it and below, in sorted order). ``skeletons`` is ``None`` (each AMC
    finds ``<subject>.asf`` beside it), one ASF for every AMC, or one per file (BVH files carry their own and
    ignore theirs). ``joint_maps`` likewise: None, one for every clip, or one per clip (``"none"`` for a clip
    whose names are recognised). Clips of different subjects are each retargeted with their own skeleton and
    keep their own lengths. ``cache``: the folder of converted clips (:mod:`data_tools.motion.cache`; True: the
    user's cache folder, None or False: convert every file afresh).
    """
    files = expand_mocap(files) if files else []
    if not files:
        raise InputError("no training clips given")
    skeletons = list(skeletons or [])
    if skeletons and len(skeletons) not in (1, len(files)):
        raise InputError(f"give one skeleton for all clips or one per clip ({len(files)}), got {len(skeletons)}")
    maps = per_clip(joint_maps, len(files), "joint map")
    results = []
    for i, f in enumerate(files):
        skel = None if not skeletons else skeletons[0 if len(skeletons) == 1 else i]
        reader = READERS.find(f.suffix.lower())  # (an unknown suffix is refused by load_mocap, after a missing file)
        if skel is not None and reader is not None and reader.skeleton is None:
            skel = None
        results.append(load_retargeted(f, skel, fps, joint_map=maps[i], cache=cache))
    return results


def load_retargeted(path: str | Path, skeleton: str | Path | None = None, fps: float | None = 60.0,
                    mm_per_unit: float | None = None, joint_map: str | Path | Mapping | None = None,
                    cache: Path | None | bool = True):
    """A mocap file read as :func:`load_mocap` reads it and retargeted at ``fps`` Hz (None: its own rate), as a
    :class:`~data_tools.motion.retarget.RetargetResult`, from the cache of converted clips when it holds it
    (:mod:`data_tools.motion.cache`; ``cache``: its folder, True: the user's, None or False: none)."""
    from data_tools.motion.cache import cached_retarget
    from data_tools.motion.retarget import retarget

    path = Path(path)
    reader = READERS.find(path.suffix.lower())
    if reader is None or not path.is_file() or (skeleton and reader.skeleton is None):
        load_mocap(path, skeleton, mm_per_unit, joint_map=joint_map)  # the one-line refusal
    found = not skeleton and reader.skeleton is not None
    if found and reader.read is read_asf_amc:
        skeleton, found = find_skeleton(path), False
    return cached_retarget(
        lambda: retarget(load_mocap(path, skeleton, mm_per_unit, joint_map=joint_map), fps=fps), path,
        skeleton=skeleton or None, joint_map=joint_map, mm_per_unit=mm_per_unit, fps=fps,
        reader_module=getattr(reader.read, "__module__", None),
        folder=None if found else cache)  # (a skeleton a plugin's reader finds itself is not in the key)
