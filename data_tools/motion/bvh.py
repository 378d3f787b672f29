"""BVH reader.

Conventions of the format, as read here:
- A joint's local rotation is the product of its rotation channels in the
  listed order, ``Zrotation Xrotation Yrotation`` -> ``Rz @ Rx @ Ry``; angles
  in degrees. Its origin is ``parent origin + R_parent @ offset``; position
  channels, the root's or any joint's, replace the offset. End sites become
  points named ``<joint>_end``.
- The rest skeleton is the hierarchy with every rotation zero and every joint
  at its offset (:func:`rest_frame`).
- The length unit is not stated in BVH files. Give it as ``mm_per_unit``, or
  let :func:`infer_unit` choose among :data:`CANDIDATE_UNITS_MM` the one that
  makes the skeleton's height closest to an adult's (1.6 m); the choice is
  recorded in the clip's ``unit``. The shared CMU conversions need this:
  10_01/10_03/11_01 are in centimetres and 131_01 in CMU's ASF unit
  (1/0.45 inch); read as inches, subject 10 would be 4 m tall.
- Data is y up or z up (:func:`up_axis` tells from the rest skeleton); y-up
  data is rotated to our z-up world on load.
- Files from game and animation pipelines often bake joint orients into the
  offsets: with every rotation zero such a skeleton lies down (along x, say),
  and only the motion's rotations stand it up. When the rest skeleton does not
  stand, the up axis and the skeleton's height (for the unit) come from the
  posed frames instead (:func:`posed_up_axis`, :func:`posed_height`); where the
  rest skeleton stands it decides, as it always has.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from data_tools.io.checks import MAX_FPS, MAX_MM_PER_UNIT, MAX_POSITION_MM, MIN_MM_PER_UNIT, check_range, real_number
from data_tools.io.textfiles import parse_floats, read_lines
from data_tools.motion.mocap import MM_PER_INCH, Y_UP_TO_Z_UP, MocapClip
from data_tools.motion.skeleton_points import PointPlan, plan_points, read_joint_map
from tracker.core.errors import InputError
from tracker.core.rotations import euler_to_matrix

#: Length units a BVH file may use (mm per unit).
CANDIDATE_UNITS_MM = {"mm": 1.0, "cm": 10.0, "inch": MM_PER_INCH, "cmu-asf (1/0.45 inch)": MM_PER_INCH / 0.45,
                      "m": 1000.0}

_CHANNELS = ("xposition", "yposition", "zposition", "xrotation", "yrotation", "zrotation")


@dataclass
class BvhJoint:
    name: str
    parent: int
    offset: np.ndarray
    channels: list[str]
    line: int
    end_offset: np.ndarray | None = None  # the joint's End Site, if any
    extra_ends: list[np.ndarray] = field(default_factory=list)


@dataclass
class BvhFile:
    path: str
    joints: list[BvhJoint]
    frame_time: float
    frames: np.ndarray  # T x channels
    header_frames: int
    row_lines: list[int] = field(default_factory=list)  # the file line of each frame


def read_bvh(path: str | Path) -> BvhFile:
    """Parse a BVH file; errors name the file and line."""
    path = Path(path)
    lines = read_lines(path, "BVH file")
    joints: list[BvhJoint] = []
    stack: list[int] = []  # joint indices; -2 marks an End Site block
    pending: tuple[str, int] | None = None
    i = 0
    in_end = False
    n_lines = len(lines)
    if not any(line.strip().upper().startswith("HIERARCHY") for line in lines[:5]):
        raise InputError("missing HIERARCHY header: not a BVH file", path, 1)
    while i < n_lines:
        ln = i + 1
        tok = lines[i].split()
        i += 1
        if not tok:
            continue
        key = tok[0].upper()
        if key == "HIERARCHY":
            continue
        if key in ("ROOT", "JOINT"):
            if len(tok) < 2:
                raise InputError(f"{key} without a name", path, ln)
            if key == "ROOT" and joints:
                raise InputError("more than one ROOT is not supported", path, ln)
            pending = (" ".join(tok[1:]), ln)
            in_end = False
        elif key == "END":
            in_end = True
            pending = None
        elif key == "{":
            if in_end:
                stack.append(-2)
            else:
                if pending is None:
                    raise InputError("'{' without a joint", path, ln)
                parent = next((s for s in reversed(stack) if s >= 0), -1)
                joints.append(BvhJoint(pending[0], parent, np.zeros(3), [], pending[1]))
                stack.append(len(joints) - 1)
                pending = None
        elif key == "}":
            if not stack:
                raise InputError("unbalanced '}'", path, ln)
            if stack.pop() == -2:
                in_end = False
        elif key == "OFFSET":
            vals = parse_floats(tok[1:], 3, path, ln, "OFFSET", MAX_POSITION_MM)
            if in_end:
                owner = next((s for s in reversed(stack) if s >= 0), None)
                if owner is None:
                    raise InputError("End Site outside a joint", path, ln)
                if joints[owner].end_offset is None:
                    joints[owner].end_offset = vals
                else:
                    joints[owner].extra_ends.append(vals)
            else:
                if not stack or stack[-1] < 0:
                    raise InputError("OFFSET outside a joint", path, ln)
                joints[stack[-1]].offset = vals
        elif key == "CHANNELS":
            if not stack or stack[-1] < 0:
                raise InputError("CHANNELS outside a joint", path, ln)
            try:
                n = int(tok[1])
            except (IndexError, ValueError):
                raise InputError("CHANNELS needs a count", path, ln) from None
            chans = [c.lower() for c in tok[2:]]
            if len(chans) != n:
                raise InputError(f"CHANNELS says {n} but lists {len(chans)}", path, ln)
            bad = [c for c in chans if c not in _CHANNELS]
            if bad:
                raise InputError(f"unknown channel(s) {bad}", path, ln)
            joints[stack[-1]].channels = chans
        elif key == "MOTION":
            break
        else:
            raise InputError(f"unexpected {tok[0]!r} in HIERARCHY", path, ln)
    else:
        raise InputError("no MOTION section (truncated file?)", path)
    if stack:
        raise InputError("HIERARCHY ends with unclosed braces", path, i)
    if not joints:
        raise InputError("no joints in HIERARCHY", path)
    # MOTION header.
    header = {}
    while i < n_lines and len(header) < 2:
        ln = i + 1
        s = " ".join(lines[i].split())  # tabs and repeated blanks as one space
        i += 1
        if not s:
            continue
        low = s.lower()
        if low.startswith("frames:"):
            try:
                header["frames"] = int(s.split(":", 1)[1])
            except ValueError:
                raise InputError(f"bad frame count {s!r}", path, ln) from None
            if header["frames"] < 1:
                raise InputError(f"frame count must be positive, got {header['frames']}", path, ln)
        elif low.startswith("frame time:"):
            try:
                header["time"] = float(s.split(":", 1)[1])
            except ValueError:
                raise InputError(f"bad frame time {s!r}", path, ln) from None
            if not np.isfinite(header["time"]) or header["time"] <= 0:
                raise InputError(f"frame time must be positive (a frame rate > 0), got {header['time']}", path, ln)
            check_range(1.0 / header["time"], "frame rate (1 / Frame Time)", path, hi=MAX_FPS, positive=True,
                        unit=" Hz", line=ln)
        else:
            raise InputError(f"expected 'Frames:' and 'Frame Time:', got {s[:40]!r}", path, ln)
    if len(header) < 2:
        raise InputError("MOTION lacks 'Frames:' or 'Frame Time:' (truncated file?)", path)
    n_chan = sum(len(j.channels) for j in joints)
    rows, row_lines = [], []
    while i < n_lines:
        ln = i + 1
        s = lines[i].split()
        i += 1
        if not s:
            continue
        if len(s) != n_chan:
            raise InputError(f"frame {len(rows) + 1} has {len(s)} values, the hierarchy has {n_chan} channels",
                             path, ln)
        try:
            rows.append([float(x) for x in s])
        except ValueError:
            raise InputError(f"frame {len(rows) + 1}: non-numeric value", path, ln) from None
        row_lines.append(ln)
    if len(rows) != header["frames"]:
        raise InputError(f"header says {header['frames']} frames but the file has {len(rows)} (truncated?)", path)
    frames = np.array(rows, float).reshape(len(rows), n_chan)
    check_range(frames, "frame values", path, hi=MAX_POSITION_MM, row_lines=row_lines)
    return BvhFile(str(path), joints, header["time"], frames, header["frames"], row_lines)




def _positions(bvh: BvhFile, frames: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Point positions ``T x J' x 3`` in file units, y up; names of joints then end sites."""
    T = frames.shape[0]
    col = 0
    R_all, p_all = [], []
    names = [j.name for j in bvh.joints]
    ends, end_names = [], []
    for j in bvh.joints:
        vals = frames[:, col:col + len(j.channels)]
        col += len(j.channels)
        rot_ch = [(c[0], k) for k, c in enumerate(j.channels) if c.endswith("rotation")]
        pos_ch = {c[0]: k for k, c in enumerate(j.channels) if c.endswith("position")}
        if rot_ch:
            R_local = euler_to_matrix(np.radians(vals[:, [k for _, k in rot_ch]]), "".join(a for a, _ in rot_ch))
        else:
            R_local = np.broadcast_to(np.eye(3), (T, 3, 3))
        if pos_ch:
            local_t = np.stack([vals[:, pos_ch[a]] if a in pos_ch else np.full(T, j.offset["xyz".index(a)])
                                for a in "xyz"], axis=1)
        else:
            local_t = np.broadcast_to(j.offset, (T, 3))
        if j.parent < 0:
            R, p = R_local, local_t
        else:
            Rp, pp = R_all[j.parent], p_all[j.parent]
            R = Rp @ R_local
            p = pp + np.einsum("tij,tj->ti", Rp, local_t)
        R_all.append(R)
        p_all.append(p)
        if j.end_offset is not None:
            ends.append(p + np.einsum("tij,j->ti", R, j.end_offset))
            end_names.append(j.name + "_end")
    return np.stack(p_all + ends, axis=1), names + end_names


def rest_frame(bvh: BvhFile) -> np.ndarray:
    """The channel values ``1 x C`` of the rest skeleton: every rotation zero, every position channel at its
    joint's offset (so a file with position channels on every joint keeps its bones in the rest pose; for a
    root alone, only where the skeleton stands moves)."""
    values = []
    for j in bvh.joints:
        values += [j.offset["xyz".index(c[0])] if c.endswith("position") else 0.0 for c in j.channels]
    return np.array([values], float).reshape(1, bvh.frames.shape[1])


def infer_unit(height: float, source: str | None = None, what: str = "rest skeleton") -> tuple[str, float]:
    """The candidate unit (name, mm per unit) that makes a skeleton ``height`` file units tall about 1.6 m.

    Log-ratio distance to 1.6 m picks the unit; the candidates differ by
    factors of 2.2 or more, so the choice is clear-cut for human skeletons.
    """
    if not height > 0:
        raise InputError(f"{what} has no height; cannot infer its length unit", source)
    return min(CANDIDATE_UNITS_MM.items(), key=lambda kv: abs(np.log(height * kv[1] / 1600.0)))


def _stance(points: np.ndarray, plan: PointPlan) -> np.ndarray:
    """Thorax minus the ankles' midpoint ``T x 3`` (file axes) of positions ``T x J x 3``."""
    thorax, left, right = np.moveaxis(plan.positions(points, ("thorax", "left_ankle", "right_ankle")), 1, 0)
    return thorax - 0.5 * (left + right)


def _standing_axis(v: np.ndarray, what: str, source: str) -> int:
    """The up axis (1: y, 2: z) of a thorax-above-ankles vector ``v`` (file axes); x, or a negative one, is
    refused, naming ``what`` stands that way."""
    axis = int(np.argmax(np.abs(v)))
    if axis == 0 or v[axis] <= 0:
        raise InputError(f"{what} stands along {'-' if v[axis] < 0 else '+'}{'xyz'[axis]} (thorax above the "
                         "ankles); only y-up and z-up files are read", source)
    return axis


def up_axis(rest: np.ndarray, plan: PointPlan, source: str) -> int:
    """The file's up axis (1: y, 2: z) from its rest skeleton ``J x 3`` (file axes): the axis along which the
    thorax stands highest above the ankles. A skeleton standing along x, or upside down, is refused."""
    return _standing_axis(_stance(rest[None], plan)[0], "the rest skeleton", source)


def posed_up_axis(posed: np.ndarray, plan: PointPlan, source: str) -> int:
    """The file's up axis (1: y, 2: z) from its posed frames ``T x J x 3`` (file axes): as :func:`up_axis`, for
    the median over frames of the thorax's place above the ankles."""
    return _standing_axis(np.median(_stance(posed, plan), axis=0), "the skeleton in its frames", source)


def posed_height(posed: np.ndarray, axis: int) -> float:
    """The skeleton's height (file units) in its posed frames ``T x J x 3``: the median over frames of its
    extent along the up ``axis``. In a walk or a wave this is about the standing height; a clip spent
    crouching or lying reads shorter (give ``mm_per_unit`` for those)."""
    return float(np.median(np.ptp(posed[:, :, axis], axis=1)))


def file_rate(frame_time: float) -> float:
    """The frame rate (Hz) a ``Frame Time`` (s) stands for: a whole number of Hz when the time is that rate's
    rounded to a few decimals (``0.033333`` is 30 Hz, ``0.008333`` 120 Hz), else ``1 / frame_time``
    (``0.0333667``: 29.97 Hz). Without the rounding, 121 frames of ``0.008333`` s would fall short of 1 s
    and lose their last sample at 60 Hz."""
    fps = 1.0 / frame_time
    whole = round(fps)
    return float(whole) if whole >= 1 and abs(fps - whole) <= 1e-4 * fps else fps


def bvh_clip(path: str | Path, mm_per_unit: float | None = None,
             joint_map: str | Path | Mapping | None = None) -> MocapClip:
    """Joint positions of a BVH file in mm, z up, at the file's frame rate (:func:`file_rate`).

    The body's points come from the joint names (a recognised convention, :mod:`data_tools.motion.joint_names`) or
    from ``joint_map`` (a JSON or TOML file, or a mapping; :func:`~data_tools.motion.skeleton_points.read_joint_map`).
    The up axis (y or z) comes from the rest skeleton (:func:`up_axis`), the length unit from its height
    (:func:`infer_unit`) unless ``mm_per_unit`` is given; where the rest skeleton does not stand (joint orients
    baked into the offsets), both come from the posed frames (:func:`posed_up_axis`, :func:`posed_height`),
    and the clip's notes say so.
    """
    bvh = read_bvh(path)
    rest, names = _positions(bvh, rest_frame(bvh))
    pos, _ = _positions(bvh, bvh.frames)
    mapping = None if joint_map is None else read_joint_map(joint_map)
    map_source = None if joint_map is None or isinstance(joint_map, Mapping) else joint_map
    try:
        plan = plan_points(names, "bvh", mapping, str(path), map_source)
    except InputError:
        if mapping is not None:
            raise
        plan = None  # readable as points; asking for the body's markers repeats the refusal
    notes = list(plan.notes) if plan else []
    axis, height, what = 1, float(np.ptp(rest[0, :, 1])), "rest skeleton"
    if plan is not None:
        try:
            axis = up_axis(rest[0], plan, str(path))
            height = float(np.ptp(rest[0, :, axis]))
        except InputError:
            axis = posed_up_axis(pos, plan, str(path))
            height, what = posed_height(pos, axis), "skeleton in its frames"
            notes.append("the rest skeleton (every rotation zero) does not stand: up axis and length unit read "
                         "from the frames")
    if mm_per_unit is None:
        unit_name, mm_per_unit = infer_unit(height, str(path), what)
        unit = (f"{unit_name[:-1]}; inferred from the skeleton's height)" if unit_name.endswith(")")
                else f"{unit_name} (inferred from the skeleton's height)")
    else:
        mm_per_unit = real_number(mm_per_unit, "length unit (mm per file unit)", path, lo=MIN_MM_PER_UNIT,
                                  hi=MAX_MM_PER_UNIT)
        unit = f"{mm_per_unit:g} mm per unit (given)"
    to_world = Y_UP_TO_Z_UP if axis == 1 else np.eye(3)
    positions = (pos * mm_per_unit) @ to_world.T
    check_range(positions, "joint positions", path, hi=MAX_POSITION_MM, unit=" mm", row_lines=bvh.row_lines)
    return MocapClip(str(path), positions, names, file_rate(bvh.frame_time), "bvh", notes, plan, unit,
                     "yz"[axis - 1])
