"""A small BVH writer for the tests: an ASF/AMC clip written out as BVH with any joint names.

Each ASF bone becomes a joint at the bone's start, whose rotation is the bone's (relative to its parent
bone's); a leaf bone ends in an End Site at the bone's end (or a named end joint, or nothing). The result
reads back (``data_tools.bvh``) to the same points as the ASF/AMC conversion.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from data_tools.asf_amc import bone_rotations, read_amc, read_asf
from data_tools.mocap import Y_UP_TO_Z_UP


def write_bvh(out: Path, asf: Path, amc: Path, names: dict[str, str], *, root: str = "Hips", prefix: str = "",
              every: int = 1, frames: int | None = None, mm_per_unit: float = 10.0, z_up: bool = False,
              bare: tuple[str, ...] = (), end_joints: dict[str, str] | None = None, drop: tuple[str, ...] = (),
              source_fps: float = 120.0) -> Path:
    """Write ``amc`` on ``asf`` as the BVH file ``out``.

    ``names``: ASF bone -> joint name (other bones are called ``Extra_<bone>``); ``prefix`` goes before every
    name (a namespace such as ``mixamorig:``). ``every``: keep every k-th frame (120 Hz -> 30 Hz with 4) of
    the first ``frames`` source frames. Lengths in ``mm_per_unit`` mm per file unit; ``z_up`` turns the data
    to z up. ``bare`` leaf bones get no End Site; ``end_joints`` (leaf bone -> name)
    writes a leaf's end as a joint of that name instead; ``drop`` leaves out these bones and all below them.
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

    def euler(R: np.ndarray) -> np.ndarray:  # intrinsic Z, X, Y: R = Rz Rx Ry, the reader's convention
        return Rotation.from_matrix(Q @ R @ Q.T).as_euler("ZXY", degrees=True)

    children = {p: [c for c in cs if c not in drop] for p, cs in skel.children.items()}
    parent_of = skel.parent_of()
    lines = ["HIERARCHY", f"ROOT {prefix}{root}", "{", "OFFSET 0 0 0",
             "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    columns = [Q @ (root_mm / mm_per_unit).T, euler(rot["root"]).T]

    def joint(bone: str, depth: int) -> None:
        pad = "  " * depth
        parent = parent_of[bone]
        offset = np.zeros(3) if parent == "root" else vector(parent)
        lines.extend([f"{pad}JOINT {prefix}{names.get(bone, 'Extra_' + bone)}", pad + "{",
                      f"{pad}  OFFSET {offset[0]:.6f} {offset[1]:.6f} {offset[2]:.6f}",
                      f"{pad}  CHANNELS 3 Zrotation Xrotation Yrotation"])
        columns.append(euler(np.swapaxes(rot[parent], -1, -2) @ rot[bone]).T)
        kids = children.get(bone, [])
        for c in kids:
            joint(c, depth + 1)
        if not kids:
            end = vector(bone)
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
    values = np.concatenate(columns, axis=0).T
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {every / source_fps:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in values]
    out.write_text("\n".join(lines) + "\n")
    return out
