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

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from data_tools.mocap import MM_PER_INCH, Y_UP_TO_Z_UP, MocapClip, check_fps, parse_floats, read_lines
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
        """Bone names, parents before children (depth first from the root)."""
        out, stack = [], list(reversed(self.children.get("root", [])))
        while stack:
            b = stack.pop()
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
    bones: dict[str, AsfBone] = {}
    children: dict[str, list[str]] = {}
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
                if length_scale <= 0:
                    raise InputError(f"units length must be positive, got {length_scale}", path, ln)
            elif key == "angle":
                if len(tok) < 2 or tok[1].lower() not in ("deg", "rad"):
                    raise InputError("units angle must be 'deg' or 'rad'", path, ln)
                degrees = tok[1].lower() == "deg"
        elif section == "root":
            if key == "order":
                root_order = [t.lower() for t in tok[1:]]
                bad = [t for t in root_order if t not in ("tx", "ty", "tz", "rx", "ry", "rz")]
                if bad or len(root_order) != 6:
                    raise InputError(f"root order must list TX TY TZ RX RY RZ in some order, got {tok[1:]}", path, ln)
            elif key == "axis":
                root_axis = _axis_order(tok[1:2], path, ln)
            elif key == "position":
                root_pos = parse_floats(tok[1:], 3, path, ln, "root position")
            elif key == "orientation":
                root_ori = parse_floats(tok[1:], 3, path, ln, "root orientation")
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
                if norm == 0 and bone["length"] != 0:
                    raise InputError(f"bone {bone['name']}: zero direction", path, bone["line"])
                bones[bone["name"]] = AsfBone(bone["name"], direction / (norm if norm else 1.0), bone["length"],
                                              bone["axis"], bone["axis_order"], bone["dofs"], bone["line"])
                bone = None
            elif bone is None:
                raise InputError(f"unexpected '{tok[0]}' outside a bone's begin/end", path, ln)
            elif key == "name":
                if len(tok) < 2:
                    raise InputError("bone name missing", path, ln)
                bone["name"] = tok[1]
            elif key == "direction":
                bone["direction"] = parse_floats(tok[1:], 3, path, ln, "bone direction")
            elif key == "length":
                bone["length"] = parse_floats(tok[1:2], 1, path, ln, "bone length")[0]
                if bone["length"] < 0:
                    raise InputError(f"bone length must be non-negative, got {bone['length']}", path, ln)
            elif key == "axis":
                bone["axis"] = parse_floats(tok[1:4], 3, path, ln, "bone axis")
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
            if key in ("begin", "end"):
                continue
            children.setdefault(tok[0], []).extend(tok[1:])
    if bone is not None:
        raise InputError(f"file ends inside the bone begun at line {bone['line']}", path)
    for sec in ("bonedata", "hierarchy"):
        if sec not in seen_sections:
            raise InputError(f"no :{sec} section: not an ASF skeleton (or truncated)", path)
    if "root" not in children:
        raise InputError("hierarchy has no line for 'root'", path)
    for parent, cs in children.items():
        for name in [parent] + cs:
            if name != "root" and name not in bones:
                raise InputError(f"hierarchy names bone '{name}' that bonedata does not define", path)
    return AsfSkeleton(str(path), MM_PER_INCH / length_scale, degrees, root_order, root_axis, root_pos, root_ori,
                       bones, children)


def _axis_order(tok: list[str], path, line) -> str:
    if len(tok) != 1 or sorted(tok[0].lower()) != ["x", "y", "z"]:
        raise InputError(f"axis order must be a permutation of XYZ, got {' '.join(tok)!r}", path, line)
    return tok[0].lower()


def _ordered_rotation(angles: np.ndarray, axes: str) -> np.ndarray:
    """Rotations applied in listed order (first axis first): ``R_last ... R_first``."""
    return euler_to_matrix(angles[..., ::-1], axes[::-1])


def read_amc(path: str | Path, skeleton: AsfSkeleton) -> dict[str, np.ndarray]:
    """Parse an AMC motion file against its skeleton: bone name -> ``T x n_dof`` values (file units).

    Checks: every bone is in the skeleton with the right number of values,
    frames are numbered 1, 2, ... without gaps, every frame has every moving
    bone (a truncated last frame is an error), values are finite.
    """
    path = Path(path)
    lines = read_lines(path, "motion file")
    n_dof = {name: len(b.dofs) for name, b in skeleton.bones.items()}
    n_dof["root"] = 6
    moving = {name for name, n in n_dof.items() if n > 0}
    frames: list[dict[str, np.ndarray]] = []
    frame_lines: list[int] = []
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
        if len(tok) == 1 and tok[0].isdigit():
            number = int(tok[0])
            if number != len(frames) + 1:
                raise InputError(f"frame number {number} follows frame {len(frames)}: frames must be numbered "
                                 "1, 2, ... without gaps", path, ln)
            if frames:
                _check_frame_complete(frames[-1], moving, path, frame_lines[-1], ln - 1)
            frames.append({})
            frame_lines.append(ln)
            header_done = True
            continue
        if not header_done:
            raise InputError(f"expected a frame number before bone data, got {s[:40]!r}", path, ln)
        name = tok[0]
        if name not in n_dof:
            raise InputError(f"bone '{name}' is not in the skeleton {Path(skeleton.path).name}", path, ln)
        vals = parse_floats(tok[1:], n_dof[name], path, ln, f"bone '{name}'")
        if name in frames[-1]:
            raise InputError(f"bone '{name}' appears twice in frame {len(frames)}", path, ln)
        frames[-1][name] = vals
    if not frames:
        raise InputError("no frames found (empty or not an AMC file)", path)
    _check_frame_complete(frames[-1], moving, path, frame_lines[-1], len(lines))
    return {name: np.stack([f[name] for f in frames]) for name in moving}


def _check_frame_complete(frame: dict, moving: set, path, start_line: int, end_line: int) -> None:
    missing = sorted(moving - set(frame))
    if missing:
        raise InputError(f"frame at line {start_line} lacks bones {', '.join(missing[:5])}"
                         f"{' ...' if len(missing) > 5 else ''} (truncated file?)", path, end_line)


def asf_amc_clip(asf_path: str | Path, amc_path: str | Path, fps: float = CMU_FPS) -> MocapClip:
    """Joint positions of an AMC motion on its ASF skeleton, in mm, z up, at the file's ``fps``."""
    fps = check_fps(fps, "source frame rate", str(amc_path))
    skel = read_asf(asf_path)
    motion = read_amc(amc_path, skel)
    T = motion["root"].shape[0]
    ang = np.pi / 180.0 if skel.degrees else 1.0
    unit = skel.mm_per_unit

    root_vals = motion["root"]
    order = skel.root_order
    trans = np.stack([root_vals[:, order.index(a)] for a in ("tx", "ty", "tz")], axis=1) + skel.root_position
    rot_axes = "".join(a[1] for a in order if a.startswith("r"))
    rot_vals = np.stack([root_vals[:, order.index("r" + a)] for a in rot_axes], axis=1) * ang
    C = _ordered_rotation(skel.root_orientation * ang, skel.root_axis_order)
    R_root = C @ _ordered_rotation(rot_vals, rot_axes) @ C.T

    names = ["root"]
    pos = [trans * unit]
    rot = {"root": R_root}
    end = {"root": pos[0]}
    parent_of = skel.parent_of()
    for b in skel.order():
        bone = skel.bones[b]
        p = parent_of[b]
        Cb = _ordered_rotation(bone.axis * ang, bone.axis_order)
        if bone.dofs:
            vals = motion[b] * ang
            axes = "".join(d[1] for d in bone.dofs)
            M = _ordered_rotation(vals, axes)
            R = rot[p] @ (Cb @ M @ Cb.T)
        else:
            R = np.broadcast_to(rot[p], (T, 3, 3))
        rot[b] = R
        end[b] = end[p] + np.einsum("tij,j->ti", R, bone.direction * bone.length * unit)
        names.append(b)
        pos.append(end[b])
    positions = np.stack(pos, axis=1) @ Y_UP_TO_Z_UP.T
    return MocapClip(str(amc_path), positions, names, fps, "asf")
