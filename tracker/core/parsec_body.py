"""The PARSEC bodytrack body model: 10 truncated cones, 31 pose numbers, as a :class:`BodyModel`.

PARSEC's ``bodytrack`` (Intel/Princeton, Apache 2.0) describes a person by the
10 cones of ``BodyShapeParameters.txt`` (torso, left thigh, left shin, right
thigh, right shin, left upper arm, left forearm, right upper arm, right
forearm, head; bottom radius, top radius, cross-section x and y scale, mm) and
18 lengths, and a pose by the 31 numbers of ``InitialPose.txt``. This module
writes that geometry as an instance of the generic kinematic tree, so the same
forward kinematics, projection and likelihood code draws and scores it.

The construction follows the published description of the tracker's geometry:

* torso (root): rotation ``Rz(a2) Rx(a0) Ry(a1)`` and translation ``a3..a5``
  (mm); its cone runs ``lengths[0]`` up the root's +z from the root origin
  (the pelvis, level with the hips).
* every other joint rotates by the *inverse* of ``Rz(c) Rx(a) Ry(b)`` for its
  angles ``(a, b, c)`` (missing ones zero), i.e. ``Ry(-b) Rx(-a) Rz(-c)``, in a
  frame obtained from its parent's by a fixed quarter or half turn.
* hips at ``(0, +lengths[1], 0)`` (left) and ``(0, -lengths[5], 0)`` (right)
  in the root frame, legs along +z of a frame turned half a turn about y;
  thorax joint at the root origin, turned half a turn about x, with the
  shoulder girdle and head ``lengths[0]`` along its -z (the top of the torso);
  clavicles ``lengths[9]`` / ``lengths[13]`` long, arms along -z of their frames.

World frame: z up, millimetres; angles in radians (the bodytrack calibration
uses the same world frame).
"""
from __future__ import annotations

import numpy as np

from tracker.core.body import EULER, FREE, BodyModel, Link, NamedPoint, Segment, MARKER_NAMES
from tracker.core.errors import InputError
from tracker.core.rotations import elementary_rotation

#: Names of the 31 pose numbers, in ``InitialPose.txt`` order.
BODYTRACK_DOF_NAMES = (
    "torso_rx", "torso_ry", "torso_rz", "torso_x", "torso_y", "torso_z",
    "left_hip_rx", "left_hip_ry", "left_hip_rz", "left_knee",
    "right_hip_rx", "right_hip_ry", "right_hip_rz", "right_knee",
    "left_clavicle_rx", "left_clavicle_ry", "left_shoulder_rx", "left_shoulder_ry", "left_shoulder_rz",
    "left_elbow",
    "right_clavicle_rx", "right_clavicle_ry", "right_shoulder_rx", "right_shoulder_ry", "right_shoulder_rz",
    "right_elbow",
    "thorax_ry", "thorax_rz", "head_rx", "head_ry", "head_rz",
)

#: The 10 cones, in ``BodyShapeParameters.txt`` order.
BODYTRACK_SEGMENT_NAMES = (
    "torso", "left_upper_leg", "left_lower_leg", "right_upper_leg", "right_lower_leg",
    "left_upper_arm", "left_lower_arm", "right_upper_arm", "right_lower_arm", "head",
)


def _fixed(*factors: tuple[str, float]) -> tuple[tuple[float, float, float], ...]:
    """Product of quarter/half turns about coordinate axes, rounded to exact 0/±1 entries."""
    R = np.eye(3)
    for axis, angle in factors:
        R = R @ elementary_rotation(axis, angle)
    return tuple(tuple(float(v) for v in row) for row in np.round(R))


_HALF_X = _fixed(("x", np.pi))
_HALF_Y = _fixed(("y", np.pi))
_LEFT_GIRDLE = _fixed(("x", -np.pi / 2))
_RIGHT_GIRDLE = _fixed(("x", np.pi / 2))
_UPPER_ARM = _fixed(("x", -np.pi / 2), ("z", np.pi), ("y", -np.pi / 2))

_NX, _NY, _NZ = (-1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0)


def ten_cone_model(limbs: np.ndarray, lengths: np.ndarray, lower: np.ndarray | None = None,
                   upper: np.ndarray | None = None, source: str | None = None) -> BodyModel:
    """The bodytrack model from its shape numbers.

    ``limbs`` ``10 x 4``: per cone bottom radius, top radius (mm), cross-section
    scale along the cone frame's x and y. ``lengths`` ``(18,)`` mm (indices 4,
    8, 12 and 16 are unused by the geometry). ``lower``/``upper`` ``(31,)``:
    pose limits (default unbounded).
    """
    limbs = np.asarray(limbs, float)
    lengths = np.asarray(lengths, float)
    if limbs.shape != (10, 4) or lengths.shape != (18,):
        raise InputError(f"bodytrack shape needs 10x4 limb numbers and 18 lengths, got {limbs.shape} and "
                         f"{lengths.shape}", source)
    if not (np.all(np.isfinite(limbs)) and np.all(np.isfinite(lengths))):
        raise InputError("bodytrack shape contains NaN or infinite values", source)
    if np.any(limbs <= 0):
        i, j = np.argwhere(limbs <= 0)[0]
        raise InputError(f"cone {BODYTRACK_SEGMENT_NAMES[i]} has a non-positive radius or scale "
                         f"({limbs[i, j]:g})", source)
    used = [0, 1, 2, 3, 5, 6, 7, 9, 10, 11, 13, 14, 15, 17]
    if np.any(lengths[used] <= 0):
        bad = [i for i in used if lengths[i] <= 0]
        raise InputError(f"bodytrack lengths {bad} must be positive (mm)", source)
    d = {name: i for i, name in enumerate(BODYTRACK_DOF_NAMES)}
    L = lengths
    links: list[Link] = []

    def add(name, parent, offset, joint, dofs, axes, rotation=None) -> int:
        links.append(Link(name, parent, tuple(float(x) for x in offset), joint, tuple(dofs), tuple(axes), rotation))
        return len(links) - 1

    torso = add("torso", -1, (0, 0, 0), FREE,
                (d["torso_x"], d["torso_y"], d["torso_z"], d["torso_rz"], d["torso_rx"], d["torso_ry"]),
                ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)))
    thorax = add("thorax", torso, (0, 0, 0), EULER, (d["thorax_ry"], d["thorax_rz"]), (_NY, _NZ), _HALF_X)
    top = (0.0, 0.0, -L[0])
    head = add("head", thorax, top, EULER, (d["head_ry"], d["head_rx"], d["head_rz"]), (_NY, _NX, _NZ), _HALF_X)
    arms = {}
    for side, girdle, clav_len, ua_len in (("left", _LEFT_GIRDLE, L[9], L[10]),
                                           ("right", _RIGHT_GIRDLE, L[13], L[14])):
        clav = add(f"{side}_clavicle", thorax, top, EULER,
                   (d[f"{side}_clavicle_ry"], d[f"{side}_clavicle_rx"]), (_NY, _NX), girdle)
        ua = add(f"{side}_upper_arm", clav, (0, 0, -clav_len), EULER,
                 (d[f"{side}_shoulder_ry"], d[f"{side}_shoulder_rx"], d[f"{side}_shoulder_rz"]), (_NY, _NX, _NZ),
                 _UPPER_ARM)
        fa = add(f"{side}_lower_arm", ua, (0, 0, -ua_len), EULER, (d[f"{side}_elbow"],), (_NY,))
        arms[side] = (ua, fa)
    legs = {}
    for side, hip_y, thigh_len in (("left", L[1], L[2]), ("right", -L[5], L[6])):
        th = add(f"{side}_upper_leg", torso, (0, hip_y, 0), EULER,
                 (d[f"{side}_hip_ry"], d[f"{side}_hip_rx"], d[f"{side}_hip_rz"]), (_NY, _NX, _NZ), _HALF_Y)
        sh = add(f"{side}_lower_leg", th, (0, 0, thigh_len), EULER, (d[f"{side}_knee"],), (_NY,))
        legs[side] = (th, sh)

    up, down = (0.0, 0.0, 1.0), (0.0, 0.0, -1.0)
    cone_link_axis_length = {
        "torso": (torso, up, L[0]), "left_upper_leg": (legs["left"][0], up, L[2]),
        "left_lower_leg": (legs["left"][1], up, L[3]), "right_upper_leg": (legs["right"][0], up, L[6]),
        "right_lower_leg": (legs["right"][1], up, L[7]), "left_upper_arm": (arms["left"][0], down, L[10]),
        "left_lower_arm": (arms["left"][1], down, L[11]), "right_upper_arm": (arms["right"][0], down, L[14]),
        "right_lower_arm": (arms["right"][1], down, L[15]), "head": (head, up, L[17]),
    }
    segments = []
    for k, name in enumerate(BODYTRACK_SEGMENT_NAMES):
        link, axis, length = cone_link_axis_length[name]
        bottom, top_r, sx, sy = limbs[k]
        segments.append(Segment(name, link, axis, float(length), float(bottom * sx), float(top_r * sx),
                                float(sy / sx), width_axis=(1.0, 0.0, 0.0)))

    def end(name: str) -> tuple[float, float, float]:
        _, axis, length = cone_link_axis_length[name]
        return tuple(float(length * a) for a in axis)

    points = [NamedPoint("pelvis", torso, (0, 0, 0)), NamedPoint("thorax", thorax, top),
              NamedPoint("head", head, end("head"))]
    for side in ("left", "right"):
        ua, fa = arms[side]
        points += [NamedPoint(f"{side}_shoulder", ua, (0, 0, 0)), NamedPoint(f"{side}_elbow", fa, (0, 0, 0)),
                   NamedPoint(f"{side}_wrist", fa, end(f"{side}_lower_arm"))]
    for side in ("left", "right"):
        th, sh = legs[side]
        points += [NamedPoint(f"{side}_hip", th, (0, 0, 0)), NamedPoint(f"{side}_knee", sh, (0, 0, 0)),
                   NamedPoint(f"{side}_ankle", sh, end(f"{side}_lower_leg"))]
    n = len(BODYTRACK_DOF_NAMES)
    lower = np.full(n, -np.inf) if lower is None else np.asarray(lower, float)
    upper = np.full(n, np.inf) if upper is None else np.asarray(upper, float)
    if lower.shape != (n,) or upper.shape != (n,) or np.any(lower > upper):
        raise InputError(f"bodytrack pose limits need {n} lower and {n} upper values with lower <= upper", source)
    return BodyModel(name="bodytrack-10-cone", links=links, segments=segments, points=points,
                     dof_names=list(BODYTRACK_DOF_NAMES), lower=lower, upper=upper, marker_names=list(MARKER_NAMES))
