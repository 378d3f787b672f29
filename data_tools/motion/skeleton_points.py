"""Which of a mocap file's points are the body model's markers: by a recognised naming convention
(:mod:`data_tools.motion.joint_names`) or by a joint map, with the points a file lacks derived from those it has.

A :class:`PointPlan` says, for each point the body model needs, which of the clip's points give it (one,
or the mean of several) or how it is derived:

- a hand end (``left_hand_end``, ``right_hand_end``): the forearm's line continued past the wrist by
  :data:`~data_tools.motion.joint_names.HAND_PER_FOREARM` of the forearm's length;
- a toe (``left_toe``, ``right_toe``): from the ankle along the body's forward axis (the frame of the hip
  line and the pelvis-to-thorax line), pitched down as :data:`~data_tools.motion.joint_names.FOOT_DIRECTION`,
  :data:`~data_tools.motion.joint_names.FOOT_PER_SHANK` of the shank's length long;
- the head end (``head``): the thorax-to-head-joint line continued by
  :data:`~data_tools.motion.joint_names.HEAD_PER_NECK` of its length or, for the conventions of
  :data:`~data_tools.motion.joint_names.HEAD_BY_TORSO`, to :data:`~data_tools.motion.joint_names.HEAD_PER_TORSO` of the
  pelvis-to-thorax length from the thorax.

Derived hands and toes only guide the fit's hand and foot angles (they are not markers); a derived head is a
marker and is said so in the clip's notes.
"""
from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from data_tools.motion.joint_names import (
    BVH, CONVENTIONS, FOOT_DIRECTION, FOOT_PER_SHANK, HAND_PER_FOREARM, HEAD_BY_TORSO, HEAD_JOINT, HEAD_PER_NECK,
    HEAD_PER_TORSO,
)
from tracker.core.body import EXTRA_POINT_NAMES, MARKER_NAMES
from tracker.core.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: Every point a plan can give: the 15 markers, the 4 extra fit points, and the head joint.
POINTS = MARKER_NAMES + EXTRA_POINT_NAMES + (HEAD_JOINT,)
#: What each derivable point is derived from (the points it needs), in words for the notes.
DERIVED_FROM = {
    "left_hand_end": (("left_elbow", "left_wrist"), "the left wrist and forearm"),
    "right_hand_end": (("right_elbow", "right_wrist"), "the right wrist and forearm"),
    "left_toe": (("left_knee", "left_ankle", "pelvis", "thorax", "left_hip", "right_hip"),
                 "the left ankle and the skeleton's forward axis"),
    "right_toe": (("right_knee", "right_ankle", "pelvis", "thorax", "left_hip", "right_hip"),
                  "the right ankle and the skeleton's forward axis"),
    "head": (("thorax", HEAD_JOINT), "the head joint, continuing the neck"),
}
DOC = "docs/guide/motion_capture.md"


def name_key(name: str) -> str:
    """How names are compared: without a namespace (``mixamorig:Hips`` -> ``hips``), case-insensitive."""
    return name.rsplit(":", 1)[-1].lower()


@dataclass
class PointPlan:
    """Where each point comes from: ``sources[point]`` is the indices of the clip's points whose mean it is,
    or ``None`` when it is derived (:data:`DERIVED_FROM`). ``naming`` says how the names were read (a
    convention's name, or the joint map's file); ``notes`` what a user should know (ignored namespaces,
    derived points); ``head_by_torso`` places a derived head end by the torso's length, not the neck's."""

    naming: str
    sources: dict[str, tuple[int, ...] | None]
    notes: list[str] = field(default_factory=list)
    head_by_torso: bool = False

    def positions(self, positions: np.ndarray, points=MARKER_NAMES + EXTRA_POINT_NAMES) -> np.ndarray:
        """The ``points`` ``T x M x 3`` (mm) from the clip's ``positions`` ``T x J x 3``."""
        cache: dict[str, np.ndarray] = {}

        def get(p: str) -> np.ndarray:
            if p not in cache:
                idx = self.sources.get(p)
                cache[p] = positions[:, list(idx)].mean(axis=1) if idx else _derive(p, get, self.head_by_torso)
            return cache[p]

        return np.stack([get(p) for p in points], axis=1)


def _derive(point: str, get, head_by_torso: bool = False) -> np.ndarray:
    """A point the file lacks, ``T x 3``, from those it has (``get(name)``)."""
    if point.endswith("hand_end"):
        side = point.split("_")[0]
        wrist = get(f"{side}_wrist")
        return wrist + HAND_PER_FOREARM * (wrist - get(f"{side}_elbow"))
    if point == "head":
        joint, thorax = get(HEAD_JOINT), get("thorax")
        if not head_by_torso:
            return joint + HEAD_PER_NECK * (joint - thorax)
        neck = joint - thorax
        torso = float(np.median(np.linalg.norm(thorax - get("pelvis"), axis=-1)))
        return thorax + HEAD_PER_TORSO * torso * neck / np.maximum(np.linalg.norm(neck, axis=-1, keepdims=True),
                                                                   1e-12)
    side = point.split("_")[0]  # a toe: along the body's forward axis, pitched down, from the ankle
    y = get("left_hip") - get("right_hip")
    y /= np.maximum(np.linalg.norm(y, axis=-1, keepdims=True), 1e-12)
    up = get("thorax") - get("pelvis")
    z = up - np.sum(up * y, axis=-1, keepdims=True) * y
    z /= np.maximum(np.linalg.norm(z, axis=-1, keepdims=True), 1e-12)
    x = np.cross(y, z)
    fx, fy, fz = FOOT_DIRECTION
    direction = fx * x + (fy if side == "left" else -fy) * y + fz * z
    ankle = get(f"{side}_ankle")
    shank = float(np.median(np.linalg.norm(get(f"{side}_knee") - ankle, axis=-1)))
    return ankle + FOOT_PER_SHANK * shank * direction


class _Names:
    """A clip's point names, looked up by :func:`name_key`; a name that two points share is refused when
    used."""

    def __init__(self, names: list[str], source):
        self.names, self.source = names, source
        self.index: dict[str, int] = {}
        self.twice: set[str] = set()
        for i, n in enumerate(names):
            k = name_key(n)
            if k in self.index:
                self.twice.add(k)
            else:
                self.index[k] = i

    def find(self, candidate) -> tuple[int, ...] | None:
        """The indices a candidate names (``@root``, a name, or a list of names for their midpoint)."""
        if candidate == "@root":
            return (0,)
        if isinstance(candidate, (list, tuple)):
            found = [self.find(c) for c in candidate]
            return None if any(f is None for f in found) else tuple(i for f in found for i in f)
        k = name_key(candidate)
        if k in self.twice:
            raise InputError(f"two joints are named {candidate!r} (namespaces and case aside); rename one or "
                             f"map the joints with --joint-map FILE ({DOC})", self.source)
        return (self.index[k],) if k in self.index else None

    def namespaces(self) -> list[str]:
        return sorted({n.rsplit(":", 1)[0] + ":" for n in self.names if ":" in n})


def _complete(sources: dict[str, tuple[int, ...] | None]) -> tuple[list[str], list[str]]:
    """Fill in the points that can be derived; returns (points derived, points missing)."""
    derived, missing = [], []
    for p in POINTS:
        if sources.get(p) is not None or p == HEAD_JOINT:
            continue
        needs = DERIVED_FROM.get(p)
        if needs and all(sources.get(n) is not None for n in needs[0]):
            sources[p] = None
            derived.append(p)
        else:
            missing.append(p)
    return derived, missing


def _derived_notes(derived: list[str], why: str = "the file has no such point") -> list[str]:
    return [f"{p} derived from {DERIVED_FROM[p][1]} ({why})" for p in derived]


def plan_points(names: list[str], style: str, joint_map: Mapping[str, object] | None = None,
                source: str | Path | None = None, map_source: str | Path | None = None) -> PointPlan:
    """The plan for a clip with point ``names`` (``style`` ``'bvh'`` or ``'asf'``): from ``joint_map`` when
    given (:func:`read_joint_map`), else from the convention that covers the names best. Refused (one
    :class:`InputError` naming ``source``) when no convention gives all 15 markers, listing the file's
    joints and pointing to ``--joint-map``."""
    found = _Names(names, source)
    if joint_map is not None:
        return _plan_from_map(found, joint_map, source, map_source)
    best = None
    for conv_name, conv_style, table in CONVENTIONS:
        if conv_style != style:
            continue
        sources = {p: next((f for f in (found.find(c) for c in table.get(p, ())) if f is not None), None)
                   for p in POINTS}
        direct = sum(v is not None for v in sources.values())
        derived, missing = _complete(sources)
        markers = sum(p not in missing for p in MARKER_NAMES)
        score = (markers, direct)
        if best is None or score > best[0]:
            best = (score, conv_name, table, sources, derived, missing)
    if best is None:
        raise InputError(f"no naming convention for {style} skeletons", source)
    _, conv_name, table, sources, derived, missing = best
    if missing:
        raise InputError(_unrecognised(names, style, conv_name if best[0][0] >= len(MARKER_NAMES) // 2 else None,
                                       table, missing), source)
    naming = f"{conv_name} names"
    spaces = found.namespaces()
    if spaces:
        naming += f" (namespace{'s' if len(spaces) > 1 else ''} {' '.join(spaces)} ignored)"
    return PointPlan(naming, sources, _derived_notes(derived), conv_name in HEAD_BY_TORSO)


def _unrecognised(names: list[str], style: str, conv_name: str | None, table: dict, missing: list[str]) -> str:
    """One line: what the nearest convention (if one comes near) lacks, the file's joints, and where to go
    from here."""
    def shown(c):
        return "+".join(c) if isinstance(c, (list, tuple)) else c

    joints = [n for n in names if not (style == BVH and n.endswith("_end"))]
    kind = "joints" if style == BVH else "bones"
    tried = ", ".join(n for n, s, _ in CONVENTIONS if s == style)
    near = ""
    if conv_name is not None:
        lacks = ", ".join(f"{p} ({' or '.join(shown(c) for c in table.get(p, ())) or '-'})" for p in missing)
        near = f"; the nearest, {conv_name}, lacks {lacks}"
    return (f"joint names not recognised (conventions known: {tried}){near}; the file's {kind}: "
            f"{', '.join(joints)}; name the body's points with --joint-map FILE (JSON or TOML, see {DOC})")


def _plan_from_map(found: _Names, joint_map: Mapping[str, object], source, map_source) -> PointPlan:
    where = map_source or "the joint map"
    sources: dict[str, tuple[int, ...] | None] = {}
    for point, value in joint_map.items():
        idx = found.find(value)
        if idx is None:
            absent = [v for v in ([value] if isinstance(value, str) else value) if found.find(v) is None]
            joints = ", ".join(found.names)
            raise InputError(f"joint map {where} names {', '.join(map(repr, absent))} for {point}, which the "
                             f"file lacks; its points: {joints}", source)
        sources[point] = idx
    derived, missing = _complete(sources)
    markers_missing = [p for p in missing if p in MARKER_NAMES]
    if markers_missing:
        raise InputError(f"joint map {where} gives no joint for {', '.join(markers_missing)} (every one of "
                         f"{', '.join(MARKER_NAMES)} is needed; hand ends, toes and the head end can be derived)",
                         source)
    return PointPlan(f"joints from the joint map {Path(str(where)).name}", sources,
                     _derived_notes(derived, "the joint map names none"))


def read_joint_map(path: str | Path | Mapping) -> dict[str, object]:
    """A joint map: our point names (:data:`POINTS`) to the file's joint names, from a JSON or TOML file (or
    a mapping given directly). A value is one name or a list of names (their midpoint). Every problem is one
    :class:`InputError` naming the file."""
    if isinstance(path, Mapping):
        raw, where = dict(path), None
    else:
        where = Path(path)
        try:
            text = where.read_text(encoding="utf-8-sig")
        except FileNotFoundError:
            raise InputError("joint map not found", where) from None
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read joint map ({exc})", where) from None
        if where.suffix.lower() == ".toml":
            try:
                raw = tomllib.loads(text)
            except tomllib.TOMLDecodeError as exc:
                raise InputError(f"joint map is not valid TOML ({exc})", where) from None
        elif where.suffix.lower() == ".json":
            try:
                raw = json.loads(text)
            except json.JSONDecodeError as exc:
                raise InputError(f"joint map is not valid JSON ({exc})", where) from None
        else:
            raise InputError("a joint map is a .json or .toml file", where)
    if not isinstance(raw, dict):
        raise InputError("a joint map is a table of point = joint name", where)
    unknown = sorted(set(raw) - set(POINTS))
    if unknown:
        raise InputError(f"joint map names unknown point(s) {', '.join(map(repr, unknown))}; the points are "
                         f"{', '.join(POINTS)}", where)
    for point, value in raw.items():
        names = value if isinstance(value, list) else [value]
        if not names or not all(isinstance(n, str) and n.strip() for n in names):
            raise InputError(f"joint map: {point} must be a joint name or a list of joint names, got {value!r}",
                             where)
    return raw
