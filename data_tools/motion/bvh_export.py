"""Tracked poses out as BVH: the body model's links as a joint hierarchy, every frame's rotations as Euler angles.

The file is y up (BVH's and Blender's importer's default: our z-up world turned so that our ``(x, y, z)`` is the
file's ``(x, z, -y)``, a proper rotation) and in ``unit`` (metres by default, so that Blender's importer at scale 1
gives a person of life size). Joints are the model's links (pelvis the root with position channels), each with
``Zrotation Xrotation Yrotation`` channels (degrees; the local rotation is ``Rz @ Rx @ Ry``); offsets are the
links' rest offsets, in the rest pose every link frame equals the world axes, so the zero-rotation skeleton is
the model's rest pose (arms hanging, facing the file's +x). End sites are the head's top, the hands' ends and the
toes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from tracker.core.body import BodyModel
from tracker.core.errors import InputError
from tracker.core.kinematics import forward_kinematics

#: Our world (z up) to the file's axes (y up): rows are the file's axes in ours.
TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
UNITS = {"m": 1000.0, "cm": 10.0, "mm": 1.0}
#: End sites: link name -> the model's point at the end of that link's segment.
_END_POINTS = {"head": "head", "left_hand": "left_hand_end", "right_hand": "right_hand_end",
               "left_foot": "left_toe", "right_foot": "right_toe"}


def _order(model: BodyModel) -> list[int]:
    """Links depth first (BVH's order of joints, channels and columns)."""
    children: dict[int, list[int]] = {}
    for i, link in enumerate(model.links):
        children.setdefault(link.parent, []).append(i)
    out: list[int] = []

    def visit(i: int) -> None:
        out.append(i)
        for c in children.get(i, []):
            visit(c)

    for root in children.get(-1, []):
        visit(root)
    return out


def write_bvh(path: str | Path, model: BodyModel, poses: np.ndarray, fps: float, unit: str = "m") -> None:
    """Write ``poses`` ``T x D`` of ``model`` as BVH at ``fps`` Hz in ``unit`` (module docstring)."""
    if unit not in UNITS:
        raise InputError(f"BVH unit must be one of {', '.join(UNITS)}, got {unit!r}")
    poses = model.check_poses(np.atleast_2d(np.asarray(poses, float)))
    scale = 1.0 / UNITS[unit]
    fk = forward_kinematics(model, poses)
    R = np.einsum("ij,tljk,mk->tlim", TO_Y_UP, fk.rotations, TO_Y_UP)  # world-from-link in the file's axes
    origins = fk.origins @ TO_Y_UP.T * scale
    order = _order(model)
    ends = {model.links.index(next(link for link in model.links if link.name == name)): point
            for name, point in _END_POINTS.items() if any(link.name == name for link in model.links)}
    points = {p.name: p for p in model.points}
    depth = {-1: -1}
    lines = ["HIERARCHY"]
    closing: list[int] = []
    for i in order:
        link = model.links[i]
        d = depth[link.parent] + 1
        depth[i] = d
        while closing and closing[-1] >= d:
            lines.append("  " * closing.pop() + "}")
        pad = "  " * d
        offset = TO_Y_UP @ np.asarray(link.offset, float) * scale
        if link.parent < 0:
            lines += [f"ROOT {link.name}", "{", "  OFFSET 0 0 0",
                      "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
        else:
            lines += [f"{pad}JOINT {link.name}", pad + "{", f"{pad}  OFFSET " + " ".join(f"{v:.6f}" for v in offset),
                      f"{pad}  CHANNELS 3 Zrotation Xrotation Yrotation"]
        if i in ends:
            end = TO_Y_UP @ np.asarray(points[ends[i]].position, float) * scale
            lines += [f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET " + " ".join(f"{v:.6f}" for v in end),
                      f"{pad}  }}"]
        closing.append(d)
    while closing:
        lines.append("  " * closing.pop() + "}")
    columns = []
    for i in order:
        parent = model.links[i].parent
        local = R[:, i] if parent < 0 else np.einsum("tji,tjk->tik", R[:, parent], R[:, i])
        angles = np.degrees(Rotation.from_matrix(local).as_euler("ZXY"))
        if parent < 0:
            columns.append(origins[:, i])
        columns.append(angles)
    frames = np.concatenate(columns, axis=1)
    lines += ["MOTION", f"Frames: {len(frames)}", f"Frame Time: {1.0 / fps:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in frames]
    Path(path).write_text("\n".join(lines) + "\n")
