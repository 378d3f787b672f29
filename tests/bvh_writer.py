"""A small BVH writer for the tests: an ASF/AMC clip written out as BVH with any joint names.

Each ASF bone becomes a joint at the bone's start, whose rotation is the bone's (relative to its parent
bone's); a leaf bone ends in an End Site at the bone's end (or a named end joint, or nothing). The result
reads back (``data_tools.motion.bvh``) to the same points as the ASF/AMC conversion.

As game and animation pipelines write them, a file may also bake joint orients into the offsets (each joint's
frame turned so that its bone runs along its own +x: with every rotation zero the skeleton lies along x),
give every joint six channels, put an extra root on the ground above the hips, and end its leaves in End
Sites at their joints.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from data_tools.motion.asf_amc import bone_rotations, read_amc, read_asf
from data_tools.motion.mocap import Y_UP_TO_Z_UP


def write_bvh(out: Path, asf: Path, amc: Path, names: dict[str, str], *, root: str = "Hips", prefix: str = "",
              every: int = 1, frames: int | None = None, mm_per_unit: float = 10.0, z_up: bool = False,
              bare: tuple[str, ...] = (), end_joints: dict[str, str] | None = None, drop: tuple[str, ...] = (),
              source_fps: float = 120.0, orients: bool = False, positions: bool = False,
              extra_root: str | None = None, zero_ends: bool = False) -> Path:
    """Write ``amc`` on ``asf`` as the BVH file ``out``.

    ``names``: ASF bone -> joint name (other bones are called ``Extra_<bone>``); ``prefix`` goes before every
    name (a namespace such as ``mixamorig:``). ``every``: keep every k-th frame (120 Hz -> 30 Hz with 4) of
    the first ``frames`` source frames. Lengths in ``mm_per_unit`` mm per file unit; ``z_up`` turns the data
    to z up. ``bare`` leaf bones get no End Site; ``end_joints`` (leaf bone -> name)
    writes a leaf's end as a joint of that name instead; ``drop`` leaves out these bones and all below them.
    ``orients`` bakes joint orients into the offsets (every bone along its joint's +x, the rest skeleton lying
    along x); ``positions`` gives every joint position channels (its offset); ``extra_root`` names a root on
    the ground at the origin, with six zero channels, above the ``root`` joint; ``zero_ends`` puts End Sites
    at their joints (offset 0).
    """
    end_joints = end_joints or {}
    skel = read_asf(asf)
    motion = read_amc(amc, skel)
    root_mm, rot = bone_rotations(skel, motion)
    keep = slice(0, frames, every)
    root_mm = root_mm[keep]
    rot = {b: r[keep] for b, r in rot.items()}
    T = len(root_mm)
    Q = Y_UP_TO_Z_UP if z_up else np.eye(3)
    to_file = skel.mm_per_unit / mm_per_unit

    def vector(bone: str) -> np.ndarray:
        b = skel.bones[bone]
        return Q @ (b.direction * b.length * to_file)

    def orient(bone: str) -> np.ndarray:
        """The frame baked into a joint (file axes): its bone's direction as +x, or none."""
        if not orients:
            return np.eye(3)
        if bone == "root":  # its children start at its origin: any fixed turn
            return Rotation.from_euler("ZX", [90.0, 30.0], degrees=True).as_matrix()
        x = vector(bone) / np.linalg.norm(vector(bone))
        y = np.cross([0.0, 0.0, 1.0] if abs(x[2]) < 0.9 else [1.0, 0.0, 0.0], x)
        y /= np.linalg.norm(y)
        return np.stack([x, y, np.cross(x, y)], axis=1)

    def euler(R: np.ndarray, inner: np.ndarray, outer: np.ndarray) -> np.ndarray:
        """Intrinsic Z, X, Y angles (R = Rz Rx Ry, the reader's convention) of ``outer.T @ Q R Q.T @ inner``: a
        local rotation between the baked frames of parent (``outer``) and joint (``inner``)."""
        return Rotation.from_matrix(outer.T @ Q @ R @ Q.T @ inner).as_euler("ZXY", degrees=True)

    six = "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"

    children = {p: [c for c in cs if c not in drop] for p, cs in skel.children.items()}
    parent_of = skel.parent_of()
    lines = ["HIERARCHY"]
    if extra_root:
        lines += [f"ROOT {prefix}{extra_root}", "{", "OFFSET 0 0 0", six, f"JOINT {prefix}{root}"]
    else:
        lines += [f"ROOT {prefix}{root}"]
    lines += ["{", "OFFSET 0 0 0", six]
    columns = ([np.zeros((6, T))] if extra_root else []) + [Q @ (root_mm / mm_per_unit).T,
                                                             euler(rot["root"], orient("root"), np.eye(3)).T]

    def joint(bone: str, depth: int) -> None:
        pad = "  " * depth
        parent = parent_of[bone]
        offset = np.zeros(3) if parent == "root" else orient(parent).T @ vector(parent)
        lines.extend([f"{pad}JOINT {prefix}{names.get(bone, 'Extra_' + bone)}", pad + "{",
                      f"{pad}  OFFSET {offset[0]:.6f} {offset[1]:.6f} {offset[2]:.6f}",
                      f"{pad}  {six}" if positions else f"{pad}  CHANNELS 3 Zrotation Xrotation Yrotation"])
        if positions:
            columns.append(np.repeat(offset[:, None], T, axis=1))
        columns.append(euler(np.swapaxes(rot[parent], -1, -2) @ rot[bone], orient(bone), orient(parent)).T)
        kids = children.get(bone, [])
        for c in kids:
            joint(c, depth + 1)
        if not kids:
            end = np.zeros(3) if zero_ends else orient(bone).T @ vector(bone)
            if bone in end_joints:
                lines.extend([f"{pad}  JOINT {prefix}{end_joints[bone]}", pad + "  {",
                              f"{pad}    OFFSET {end[0]:.6f} {end[1]:.6f} {end[2]:.6f}",
                              f"{pad}    CHANNELS 3 Zrotation Xrotation Yrotation",
                              f"{pad}    End Site", pad + "    {", f"{pad}      OFFSET 0 1 0", pad + "    }",
                              pad + "  }"])
                columns.append(np.zeros((3, T)))
            elif bone not in bare:
                lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET {end[0]:.6f} {end[1]:.6f} "
                                                                  f"{end[2]:.6f}", pad + "  }"])
        lines.append(pad + "}")

    for c in children.get("root", []):
        joint(c, 1)
    lines.append("}")
    if extra_root:
        lines.append("}")
    values = np.concatenate(columns, axis=0).T
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {every / source_fps:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in values]
    out.write_text("\n".join(lines) + "\n")
    return out
