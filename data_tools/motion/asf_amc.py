"""Acclaim ASF (skeleton) and AMC (motion) reader, as used by the CMU mocap database.

Conventions of the format, as read here:
- ASF lengths are in the file's unit: ``:units length s`` means one unit is
  ``1/s`` inches (CMU FAQ), so ``25.4 / s`` mm. AMC root translations use the
  same unit. Angles are degrees unless ``angle rad`` / ``:RADIANS``.
- A bone's ``axis a b c XYZ`` gives its local frame C as rotations applied in
  the listed order (x first), i.e. ``C = Rz(c) Ry(b) Rx(a)``; a bone's motion
  ``dof rx ry rz`` is applied the same way, ``M = Rz Ry Rx``. The bone's
  world rotation is ``R = R_parent C M C^T`` and its end is
  ``start + R @ (direction * length)``; directions are in the rest (global) frame.
- CMU data is y up; positions are rotated to our z-up world on load.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from data_tools.io.checks import (
    MAX_ANGLE_DEG, MAX_BODY_MM, MAX_MM_PER_UNIT, MAX_POSITION_MM, MIN_MM_PER_UNIT, check_range,
)
from data_tools.io.textfiles import parse_floats, read_lines
from data_tools.motion.mocap import MM_PER_INCH, Y_UP_TO_Z_UP, MocapClip, check_fps
from tracker.core.errors import InputError
from tracker.core.rotations import euler_to_matrix

#: The CMU database records at 120 Hz; AMC files do not say so themselves.
CMU_FPS = 120.0


@dataclass
class AsfBone:
    name: str
    direction: np.ndarray  # (3,) unit, rest frame
    length: float  # file units
    axis: np.ndarray  # (3,) angles (file angle unit)
    axis_order: str  # e.g. 'xyz'
    dofs: list[str]  # e.g. ['rx', 'ry', 'rz']
    line: int


@dataclass
class AsfSkeleton:
    path: str
    mm_per_unit: float
    degrees: bool
    root_order: list[str]  # e.g. ['tx', 'ty', 'tz', 'rx', 'ry', 'rz']
    root_axis_order: str
    root_position: np.ndarray
    root_orientation: np.ndarray
    bones: dict[str, AsfBone]
    children: dict[str, list[str]]  # 'root' -> [...]

    def order(self) -> list[str]:
        """Bone names, parents before children (depth first from the root); a cycle is an :class:`InputError`."""
        out, seen, stack = [], {"root"}, list(reversed(self.children.get("root", [])))
        while stack:
            b = stack.pop()
            if b in seen:
                raise InputError(f"hierarchy reaches bone '{b}' twice (a cycle or a bone with two parents)",
                                 self.path)
            seen.add(b)
            out.append(b)
            stack.extend(reversed(self.children.get(b, [])))
        return out

    def parent_of(self) -> dict[str, str]:
        return {c: p for p, cs in self.children.items() for c in cs}




def read_asf(path: str | Path) -> AsfSkeleton:
    """Parse an ASF skeleton file; errors name the file and line."""
    path = Path(path)
    lines = read_lines(path, "skeleton file")
    length_scale, degrees = 1.0, True
    root_order = ["tx", "ty", "tz", "rx", "ry", "rz"]
    root_axis, root_pos, root_ori = "xyz", np.zeros(3), np.zeros(3)
    root_pos_line: int | None = None
    bones: dict[str, AsfBone] = {}
    children: dict[str, list[str]] = {}
    parent_line: dict[str, tuple[str, int]] = {}  # child -> (parent, hierarchy line)
    section = None
    bone: dict | None = None
    seen_sections = set()
    i = 0
    while i < len(lines):
        raw = lines[i]
        ln = i + 1
        i += 1
        s = raw.split("#", 1)[0].strip()
        if not s:
            continue
        tok = s.split()
        if tok[0].startswith(":"):
            section = tok[0][1:].lower()
            seen_sections.add(section)
            continue
        key = tok[0].lower()
        if section == "units":
            if key == "length":
                length_scale = parse_floats(tok[1:2], 1, path, ln, "units length")[0]
                check_range(length_scale, "units length", path, lo=MM_PER_INCH / MAX_MM_PER_UNIT,
                            hi=MM_PER_INCH / MIN_MM_PER_UNIT, unit=" (one unit is 25.4/length mm)", line=ln)
            elif key == "angle":
                if len(tok) < 2 or tok[1].lower() not in ("deg", "rad"):
                    raise InputError("units angle must be 'deg' or 'rad'", path, ln)
                degrees = tok[1].lower() == "deg"
        elif section == "root":
            if key == "order":
                root_order = [t.lower() for t in tok[1:]]
                if sorted(root_order) != ["rx", "ry", "rz", "tx", "ty", "tz"]:
                    raise InputError(f"root order must list TX TY TZ RX RY RZ in some order, got {tok[1:]}", path, ln)
            elif key == "axis":
                root_axis = _axis_order(tok[1:2], path, ln)
            elif key == "position":
                root_pos, root_pos_line = parse_floats(tok[1:], 3, path, ln, "root position"), ln
            elif key == "orientation":
                root_ori = parse_floats(tok[1:], 3, path, ln, "root orientation", MAX_ANGLE_DEG)
        elif section == "bonedata":
            if key == "begin":
                bone = {"line": ln, "dofs": [], "axis": np.zeros(3), "axis_order": "xyz"}
            elif key == "end":
                if bone is None:
                    raise InputError("'end' without 'begin' in bonedata", path, ln)
                for req in ("name", "direction", "length"):
                    if req not in bone:
                        raise InputError(f"bone starting at line {bone['line']} lacks '{req}'", path, ln)
                direction = bone["direction"]
                norm = np.linalg.norm(direction)
                if norm < 1e-12 and bone["length"] != 0:
                    raise InputError(f"bone {bone['name']}: zero direction", path, bone["line"])
                if bone["name"] in bones or bone["name"] == "root":
                    raise InputError(f"bone '{bone['name']}' is defined twice", path, bone["line"])
                bones[bone["name"]] = AsfBone(bone["name"], direction / (norm if norm >= 1e-12 else 1.0),
                                              bone["length"], bone["axis"], bone["axis_order"], bone["dofs"],
                                              bone["line"])
                bone = None
            elif bone is None:
                raise InputError(f"unexpected '{tok[0]}' outside a bone's begin/end", path, ln)
            elif key == "name":
                if len(tok) < 2:
                    raise InputError("bone name missing", path, ln)
                bone["name"] = tok[1]
            elif key == "direction":
                bone["direction"] = parse_floats(tok[1:], 3, path, ln, "bone direction", MAX_POSITION_MM)
            elif key == "length":
                bone["length"] = parse_floats(tok[1:2], 1, path, ln, "bone length")[0]
                if bone["length"] < 0:
                    raise InputError(f"bone length must be non-negative, got {bone['length']}", path, ln)
            elif key == "axis":
                bone["axis"] = parse_floats(tok[1:4], 3, path, ln, "bone axis", MAX_ANGLE_DEG)
                bone["axis_order"] = _axis_order(tok[4:5], path, ln)
            elif key == "dof":
                dofs = [t.lower() for t in tok[1:]]
                bad = [t for t in dofs if t not in ("rx", "ry", "rz", "tx", "ty", "tz", "l")]
                if bad:
                    raise InputError(f"unknown dof {bad}", path, ln)
                if any(t in ("tx", "ty", "tz", "l") for t in dofs):
                    raise InputError("translation / length dofs on bones are not supported", path, ln)
                bone["dofs"] = dofs
            # 'id', 'limits' and its continuation lines are not needed.
        elif section == "hierarchy":
            if key not in ("begin", "end"):
                _add_children(tok[0], tok[1:], children, parent_line, path, ln)
    if bone is not None:
        raise InputError(f"file ends inside the bone begun at line {bone['line']}", path)
    for sec in ("bonedata", "hierarchy"):
        if sec not in seen_sections:
            raise InputError(f"no :{sec} section: not an ASF skeleton (or truncated)", path)
    if "root" not in children:
        raise InputError("hierarchy has no line for 'root'", path)
    mm = MM_PER_INCH / length_scale
    check_range(root_pos, "root position", path, hi=MAX_POSITION_MM, unit=" mm", line=root_pos_line, scale=mm)
    for b in bones.values():
        check_range(b.length, f"bone {b.name} length", path, lo=0.0, hi=MAX_BODY_MM, unit=" mm", line=b.line,
                    scale=mm)
    skeleton = AsfSkeleton(str(path), mm, degrees, root_order, root_axis, root_pos, root_ori, bones, children)
    _check_tree(skeleton, parent_line)
    return skeleton


def _add_children(parent: str, kids: list[str], children: dict[str, list[str]],
                  parent_line: dict[str, tuple[str, int]], path: Path, line: int) -> None:
    """Record one hierarchy line, refusing the root as a child and a bone with two parents."""
    for c in kids:
        if c == "root":
            raise InputError(f"hierarchy names the root as a child of '{parent}': the root has no parent", path, line)
        if c in parent_line:
            first, first_line = parent_line[c]
            raise InputError(f"bone '{c}' has two parents: '{first}' (line {first_line}) and '{parent}'; "
                             "a skeleton is a tree", path, line)
        parent_line[c] = (parent, line)
    children.setdefault(parent, []).extend(kids)


def _check_tree(skeleton: AsfSkeleton, parent_line: dict[str, tuple[str, int]]) -> None:
    """Every hierarchy name is a defined bone, every bone hangs from the root, and there is no cycle."""
    path = Path(skeleton.path)
    for child, (parent, line) in parent_line.items():
        for name in (parent, child):
            if name != "root" and name not in skeleton.bones:
                raise InputError(f"hierarchy names bone '{name}' that bonedata does not define", path, line)
    for parent in skeleton.children:
        if parent != "root" and parent not in skeleton.bones:
            raise InputError(f"hierarchy names bone '{parent}' that bonedata does not define", path)
    reached = set(skeleton.order())  # terminates: every bone has at most one parent and the root none
    for name, (parent, line) in parent_line.items():
        if name not in reached:
            raise InputError(f"bone '{name}' (child of '{parent}') is not connected to the root "
                             "(the hierarchy has a cycle or a parent missing)", path, line)
    for name, bone in skeleton.bones.items():
        if name not in reached:
            raise InputError(f"bone '{name}' is not in the hierarchy", path, bone.line)


def _axis_order(tok: list[str], path, line) -> str:
    if len(tok) != 1 or sorted(tok[0].lower()) != ["x", "y", "z"]:
        raise InputError(f"axis order must be a permutation of XYZ, got {' '.join(tok)!r}", path, line)
    return tok[0].lower()


def _ordered_rotation(angles: np.ndarray, axes: str) -> np.ndarray:
    """Rotations applied in listed order (first axis first): ``R_last ... R_first``."""
    return euler_to_matrix(angles[..., ::-1], axes[::-1])


def read_amc(path: str | Path, skeleton: AsfSkeleton) -> dict[str, np.ndarray]:
    """Parse an AMC motion file against its skeleton: bone name -> ``T x n_dof`` values (file units).

    Checks: every bone is in the skeleton with the right number of values
    (otherwise the skeleton is likely another subject's or format's), frames
    are numbered 1, 2, ... without gaps, every frame has every moving bone (a
    truncated last frame is an error), values are finite and plausible: root
    positions within :data:`~data_tools.io.checks.MAX_POSITION_MM` of the origin,
    angles within :data:`~data_tools.io.checks.MAX_ANGLE_DEG`.
    """
    path = Path(path)
    lines = read_lines(path, "motion file")
    n_dof = {name: len(b.dofs) for name, b in skeleton.bones.items()}
    n_dof["root"] = 6
    moving = {name for name, n in n_dof.items() if n > 0}
    root_t = [k for k, a in enumerate(skeleton.root_order) if a.startswith("t")]
    root_r = [k for k, a in enumerate(skeleton.root_order) if a.startswith("r")]
    asf_name = Path(skeleton.path).name
    frames: list[dict[str, np.ndarray]] = []
    frame_lines: list[int] = []
    value_lines: dict[str, list[int]] = {name: [] for name in moving}  # per bone, the line of each frame's values
    header_done = False
    for i, raw in enumerate(lines):
        ln = i + 1
        s = raw.strip()
        if not s or s.startswith("#"):
            continue
        if s.startswith(":"):
            if s.upper() == ":RADIANS":
                skeleton.degrees = False
            elif s.upper() == ":DEGREES":
                skeleton.degrees = True
            continue
        tok = s.split()
        if len(tok) == 1 and tok[0].isascii() and tok[0].isdigit():
            number = int(tok[0])
            if number != len(frames) + 1:
                raise InputError(f"frame number {number} follows frame {len(frames)}: frames must be numbered "
                                 "1, 2, ... without gaps", path, ln)
            if frames:
                _check_frame_complete(frames, moving, asf_name, path, frame_lines[-1], ln - 1)
            frames.append({})
            frame_lines.append(ln)
            header_done = True
            continue
        if not header_done:
            raise InputError(f"expected a frame number before bone data, got {s[:40]!r}", path, ln)
        name = tok[0]
        if name not in n_dof:
            raise InputError(f"bone '{name}' is not in the skeleton {asf_name}: is that this motion's skeleton?",
                             path, ln)
        if len(tok) - 1 != n_dof[name]:
            raise InputError(f"bone '{name}' has {len(tok) - 1} values but the skeleton {asf_name} gives it "
                             f"{n_dof[name]} dof: is that this motion's skeleton?", path, ln)
        vals = parse_floats(tok[1:], None, path, ln, f"bone '{name}'")
        if name in frames[-1]:
            raise InputError(f"bone '{name}' appears twice in frame {len(frames)}", path, ln)
        frames[-1][name] = vals
        value_lines[name].append(ln)
    if not frames:
        raise InputError("no frames found (empty or not an AMC file)", path)
    _check_frame_complete(frames, moving, asf_name, path, frame_lines[-1], len(lines))
    motion = {name: np.stack([f[name] for f in frames]) for name in moving}
    angle_limit, angle_unit = (MAX_ANGLE_DEG, " degrees") if skeleton.degrees else (np.radians(MAX_ANGLE_DEG),
                                                                                    " radians")
    check_range(motion["root"][:, root_t], "root position", path, hi=MAX_POSITION_MM, unit=" mm",
                row_lines=value_lines["root"], scale=skeleton.mm_per_unit)
    for name, values in motion.items():
        angles = values[:, root_r] if name == "root" else values
        check_range(angles, f"bone '{name}' angles", path, hi=angle_limit, unit=angle_unit,
                    row_lines=value_lines[name])
    return motion


def _check_frame_complete(frames: list[dict], moving: set, asf_name: str, path: Path, start_line: int,
                          end_line: int) -> None:
    """The last frame of ``frames`` has every moving bone (the first frame's gaps mean a foreign skeleton)."""
    missing = sorted(moving - set(frames[-1]))
    if missing:
        names = f"{', '.join(missing[:5])}{' ...' if len(missing) > 5 else ''}"
        if len(frames) == 1:
            raise InputError(f"the first frame (line {start_line}) lacks bones {names} that the skeleton "
                             f"{asf_name} moves: is that this motion's skeleton (or is the file truncated)?",
                             path, end_line)
        raise InputError(f"frame at line {start_line} lacks bones {names} (truncated file?)", path, end_line)


def asf_amc_clip(asf_path: str | Path, amc_path: str | Path, fps: float = CMU_FPS) -> MocapClip:
    """Joint positions of an AMC motion on its ASF skeleton, in mm, z up, at the file's ``fps``.

    Files named the CMU way (``<subject>.asf``, ``<subject>_<trial>.amc``) must
    name the same subject: every CMU skeleton has the same bones, so a foreign
    skeleton cannot be told from the data, only from the names.
    """
    fps = check_fps(fps, "source frame rate", str(amc_path))
    _check_same_subject(Path(asf_path), Path(amc_path))
    skel = read_asf(asf_path)
    root, rotations = bone_rotations(skel, read_amc(amc_path, skel))
    unit = skel.mm_per_unit
    names = ["root"]
    pos = [root]
    end = {"root": root}
    parent_of = skel.parent_of()
    for b in skel.order():
        bone = skel.bones[b]
        end[b] = end[parent_of[b]] + np.einsum("tij,j->ti", rotations[b], bone.direction * bone.length * unit)
        names.append(b)
        pos.append(end[b])
    positions = np.stack(pos, axis=1) @ Y_UP_TO_Z_UP.T
    return MocapClip(str(amc_path), positions, names, fps, "asf", unit=f"ASF units of {unit:.4g} mm", up="y")


def bone_rotations(skel: AsfSkeleton, motion: dict[str, np.ndarray]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The root's position ``T x 3`` (mm, the file's y-up axes) and every bone's rotation ``T x 3 x 3`` from
    the rest frame (``'root'`` included), for an AMC ``motion`` (:func:`read_amc`) on ``skel``."""
    T = motion["root"].shape[0]
    ang = np.pi / 180.0 if skel.degrees else 1.0
    root_vals = motion["root"]
    order = skel.root_order
    trans = np.stack([root_vals[:, order.index(a)] for a in ("tx", "ty", "tz")], axis=1) + skel.root_position
    rot_axes = "".join(a[1] for a in order if a.startswith("r"))
    rot_vals = np.stack([root_vals[:, order.index("r" + a)] for a in rot_axes], axis=1) * ang
    C = _ordered_rotation(skel.root_orientation * ang, skel.root_axis_order)
    rot = {"root": C @ _ordered_rotation(rot_vals, rot_axes) @ C.T}
    parent_of = skel.parent_of()
    for b in skel.order():
        bone = skel.bones[b]
        p = parent_of[b]
        if bone.dofs:
            Cb = _ordered_rotation(bone.axis * ang, bone.axis_order)
            M = _ordered_rotation(motion[b] * ang, "".join(d[1] for d in bone.dofs))
            rot[b] = rot[p] @ (Cb @ M @ Cb.T)
        else:
            rot[b] = np.broadcast_to(rot[p], (T, 3, 3))
    return trans * skel.mm_per_unit, rot


def _check_same_subject(asf: Path, amc: Path) -> None:
    """Refuse a CMU-named skeleton of one subject paired with a CMU-named motion of another."""
    trial = re.fullmatch(r"(\d+)_\w+", amc.stem)
    if trial and asf.stem.isascii() and asf.stem.isdigit() and int(trial.group(1)) != int(asf.stem):
        raise InputError(f"motion of CMU subject {trial.group(1)} paired with the skeleton of subject {asf.stem} "
                         f"({asf}); use {trial.group(1)}.asf (or rename the skeleton if the pairing is intended)",
                         amc)
