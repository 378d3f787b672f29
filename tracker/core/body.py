"""Body models: a kinematic tree of links, cone segments on them, a pose layout and named points.

Convention
----------
World frame right-handed, z up, millimetres. Every link frame equals the world
axes in the rest pose (all pose parameters zero except the root height): the
body faces +x, its left side is +y, up is +z. Angles in radians; 3-dof joints
are exponential maps, 1- and 2-dof joints rotate about fixed axes of their
parent link, applied left to right (``R = R(a0, q0) @ R(a1, q1)``).

The 15-cone model of Taylor (2009, Sec. 6.3.2) is built by
:func:`fifteen_cone_model` from a :class:`BodyShape`. Other models (the PARSEC
bodytrack 10-cone variant) are other instances of :class:`BodyModel`: a list of
links, segments, a pose layout with limits, and named points.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field, replace

import numpy as np

from tracker.core.arrays import device, is_torch_array, namespace
from tracker.core.errors import InputError

# ---------------------------------------------------------------------------
# Generic structure
# ---------------------------------------------------------------------------

FREE, BALL, EULER = "free", "ball", "euler"


@dataclass(frozen=True)
class Link:
    """One rigid frame of the kinematic tree.

    ``offset`` (3,) mm: position of this link's origin (its joint centre) in the
    parent link's frame. ``joint`` is ``'free'`` (x, y, z in mm then the
    orientation: an exp map, or one angle per row of ``axes`` when ``axes`` is
    given), ``'ball'`` (3: an exp map), or ``'euler'`` (one angle per row of
    ``axes``, each a unit axis, applied left to right). ``dofs`` are the indices
    of this joint's numbers in the pose vector. ``rotation`` (3x3, row-major,
    optional) is a fixed rotation between the parent frame and the joint:
    ``R_parent_from_link = rotation @ R_joint(q)``; the 15-cone model has none
    (every link frame equals the world axes at rest), the PARSEC 10-cone model
    uses it for its flipped limb frames.
    """

    name: str
    parent: int
    offset: tuple[float, float, float]
    joint: str
    dofs: tuple[int, ...] = ()
    axes: tuple[tuple[float, float, float], ...] = ()
    rotation: tuple[tuple[float, float, float], ...] | None = None


@dataclass(frozen=True)
class Segment:
    """A truncated cone with elliptical cross-section, fixed to a link.

    The cone starts at the link origin and runs ``length`` mm along ``axis`` (a
    unit vector in the link frame). Its cross-section has semi-axis ``radius``
    along ``width_axis`` (unit, perpendicular to ``axis``) and
    ``radius * depth_scale`` along ``axis x width_axis``; the radius goes
    linearly from ``radius_proximal`` to ``radius_distal`` (mm).
    """

    name: str
    link: int
    axis: tuple[float, float, float]
    length: float
    radius_proximal: float
    radius_distal: float
    depth_scale: float
    width_axis: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def frame_in_link(self) -> np.ndarray:
        """Rotation (3, 3) whose columns are the segment axes (width, depth, axis) in link coordinates."""
        z = np.asarray(self.axis, float)
        x = np.asarray(self.width_axis, float)
        return np.stack([x, np.cross(z, x), z], axis=1)


@dataclass(frozen=True)
class NamedPoint:
    """A point fixed in a link frame (mm): markers and other points of interest."""

    name: str
    link: int
    position: tuple[float, float, float]


@dataclass
class BodyModel:
    """A body model: links, segments, pose layout (names and limits) and named points.

    ``markers`` names the points that make up the marker set used for the
    marker error (15 for the HumanEva-style set); ``points`` may hold more.
    """

    name: str
    links: list[Link]
    segments: list[Segment]
    points: list[NamedPoint]
    dof_names: list[str]
    lower: np.ndarray
    upper: np.ndarray
    marker_names: list[str]
    shape: "BodyShape | None" = None
    rest_root_height: float = 0.0
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def n_dofs(self) -> int:
        return len(self.dof_names)

    def dof_index(self, name: str) -> int:
        """Index of a named pose number (e.g. ``'left_elbow_flexion'``)."""
        try:
            return self.dof_names.index(name)
        except ValueError:
            raise KeyError(f"no pose parameter named {name!r}; known: {', '.join(self.dof_names)}") from None

    def point_index(self, name: str) -> int:
        for i, p in enumerate(self.points):
            if p.name == name:
                return i
        raise KeyError(f"no point named {name!r}")

    @property
    def marker_indices(self) -> np.ndarray:
        """Indices into ``points`` of the marker set, in marker order."""
        if "marker_indices" not in self._cache:
            self._cache["marker_indices"] = np.array([self.point_index(n) for n in self.marker_names])
        return self._cache["marker_indices"]

    def rest_pose(self) -> np.ndarray:
        """Pose (n_dofs,) with every angle zero and the root at ``rest_root_height`` above the origin."""
        q = np.zeros(self.n_dofs)
        root = self.links[0]
        if root.joint == FREE:
            q[root.dofs[2]] = self.rest_root_height
        return q

    def within_limits(self, poses):
        """Boolean ``(...)``: every number of each pose ``(..., n_dofs)`` finite and within its limits (numpy
        arrays, or torch tensors on any device)."""
        if not is_torch_array(poses):
            poses = np.asarray(poses, float)
        xp, dev = namespace(poses), device(poses)
        lower = xp.asarray(self.lower, dtype=poses.dtype, device=dev)
        upper = xp.asarray(self.upper, dtype=poses.dtype, device=dev)
        # an infinite root position is within its limits (they are infinite) but no pose
        return xp.all((poses >= lower) & (poses <= upper) & xp.isfinite(poses), axis=-1)

    def clip_to_limits(self, poses: np.ndarray) -> np.ndarray:
        return np.clip(poses, self.lower, self.upper)

    def check_poses(self, poses: np.ndarray, what: str = "poses") -> np.ndarray:
        """Validate a pose array's last dimension and finiteness; returns it as float64."""
        poses = np.asarray(poses, dtype=float)
        if poses.ndim == 0 or poses.shape[-1] != self.n_dofs:
            raise InputError(f"{what} must have shape (..., {self.n_dofs}) for the {self.name} model, got {poses.shape}")
        if not np.all(np.isfinite(poses)):
            raise InputError(f"{what} contain NaN or infinite values")
        return poses


# ---------------------------------------------------------------------------
# The 15-cone, 40-dof model
# ---------------------------------------------------------------------------

SEGMENT_NAMES = (
    "pelvis", "torso", "head",
    "left_upper_arm", "left_lower_arm", "left_hand",
    "right_upper_arm", "right_lower_arm", "right_hand",
    "left_upper_leg", "left_lower_leg", "left_foot",
    "right_upper_leg", "right_lower_leg", "right_foot",
)

MARKER_NAMES = (
    "pelvis", "thorax", "head",
    "left_shoulder", "left_elbow", "left_wrist",
    "right_shoulder", "right_elbow", "right_wrist",
    "left_hip", "left_knee", "left_ankle",
    "right_hip", "right_knee", "right_ankle",
)

#: Points beyond the 15 markers that retargeting also fits (segment ends).
EXTRA_POINT_NAMES = ("left_hand_end", "right_hand_end", "left_toe", "right_toe")

_DEG = np.pi / 180.0


def _dof_layout() -> list[tuple[str, float, float]]:
    """(name, lower, upper) of the 40 pose numbers, in the pose layout's block order (docs/reference/body_model.md).

    Limits are axis-aligned boxes. For 1- and 2-dof joints they are clinical
    ranges of motion (AAOS, Kapandji) widened by about 10 degrees. For 3-dof
    joints they bound each exponential-map component, sized from the same
    tables (the largest single-axis range plus a margin, since combined
    rotations spread over several components); the box was checked against every
    clip in ../shared/mocap after retargeting (see docs/body_model.md).
    Positive angles: flexion, abduction, elevation, protraction, plantarflexion.
    """
    inf = np.inf
    d = _DEG
    layout = [
        ("root_x", -inf, inf), ("root_y", -inf, inf), ("root_z", -inf, inf),
        ("root_rx", -inf, inf), ("root_ry", -inf, inf), ("root_rz", -inf, inf),
    ]
    # 3-dof joints (exp-map components about the link's x, y, z axes).
    # Hips: flexion is rotation about -y (leg swings forward), abduction about +x
    # for the left leg (-x for the right), internal rotation about z.
    layout += [("left_hip_x", -40 * d, 80 * d), ("left_hip_y", -140 * d, 50 * d), ("left_hip_z", -70 * d, 70 * d)]
    layout += [("right_hip_x", -80 * d, 40 * d), ("right_hip_y", -140 * d, 50 * d), ("right_hip_z", -70 * d, 70 * d)]
    # Shoulders: abduction about +x for the left arm (-x right), flexion about -y.
    layout += [("left_shoulder_x", -70 * d, 190 * d), ("left_shoulder_y", -190 * d, 90 * d),
               ("left_shoulder_z", -120 * d, 120 * d)]
    layout += [("right_shoulder_x", -190 * d, 70 * d), ("right_shoulder_y", -190 * d, 90 * d),
               ("right_shoulder_z", -120 * d, 120 * d)]
    layout += [("head_x", -60 * d, 60 * d), ("head_y", -80 * d, 90 * d), ("head_z", -90 * d, 90 * d)]
    layout += [("abdomen_x", -50 * d, 50 * d), ("abdomen_y", -60 * d, 100 * d), ("abdomen_z", -60 * d, 60 * d)]
    # 2-dof joints.
    layout += [("left_clavicle_elevation", -25 * d, 50 * d), ("left_clavicle_protraction", -35 * d, 35 * d)]
    layout += [("right_clavicle_elevation", -25 * d, 50 * d), ("right_clavicle_protraction", -35 * d, 35 * d)]
    layout += [("left_elbow_flexion", -10 * d, 160 * d), ("left_elbow_twist", -100 * d, 100 * d)]
    layout += [("right_elbow_flexion", -10 * d, 160 * d), ("right_elbow_twist", -100 * d, 100 * d)]
    layout += [("left_knee_flexion", -10 * d, 160 * d), ("left_knee_twist", -50 * d, 50 * d)]
    layout += [("right_knee_flexion", -10 * d, 160 * d), ("right_knee_twist", -50 * d, 50 * d)]
    # 1-dof joints.
    layout += [("left_wrist_flexion", -90 * d, 100 * d), ("right_wrist_flexion", -90 * d, 100 * d)]
    layout += [("left_ankle_flexion", -50 * d, 70 * d), ("right_ankle_flexion", -50 * d, 70 * d)]
    return layout


DOF_LAYOUT = _dof_layout()
DOF_NAMES = [n for n, _, _ in DOF_LAYOUT]
assert len(DOF_NAMES) == 40


def _dofs(prefix: str, n: int | None = None) -> tuple[int, ...]:
    idx = tuple(i for i, name in enumerate(DOF_NAMES) if name.startswith(prefix + "_"))
    if n is not None:
        assert len(idx) == n, (prefix, idx)
    return idx


@dataclass
class BodyShape:
    """Per-subject shape of the 15-cone model (all mm, angles in radians).

    ``lengths``, ``radius_proximal``, ``radius_distal``, ``depth_scale``: one
    value per segment name of :data:`SEGMENT_NAMES`. Offsets are rest-pose
    vectors in the parent link frame: hips from the pelvis origin, shoulders
    from the thorax point (end of the torso, through the clavicle joint), the
    abdomen joint from the pelvis origin. ``foot_pitch`` tilts the rest foot
    axis below the horizontal.
    """

    lengths: dict[str, float]
    radius_proximal: dict[str, float]
    radius_distal: dict[str, float]
    depth_scale: dict[str, float]
    left_hip_offset: tuple[float, float, float]
    right_hip_offset: tuple[float, float, float]
    left_shoulder_offset: tuple[float, float, float]
    right_shoulder_offset: tuple[float, float, float]
    abdomen_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    foot_pitch: float = 0.3

    def validate(self, source: str | None = None) -> "BodyShape":
        for table_name in ("lengths", "radius_proximal", "radius_distal", "depth_scale"):
            table = getattr(self, table_name)
            missing = [s for s in SEGMENT_NAMES if s not in table]
            if missing:
                raise InputError(f"body shape {table_name} lacks segments: {', '.join(missing)}", source)
            for s in SEGMENT_NAMES:
                v = float(table[s])
                if not np.isfinite(v) or v <= 0:
                    raise InputError(f"body shape {table_name}[{s}] must be positive and finite, got {v}", source)
        for off_name in ("left_hip_offset", "right_hip_offset", "left_shoulder_offset", "right_shoulder_offset",
                         "abdomen_offset"):
            off = np.asarray(getattr(self, off_name), float)
            if off.shape != (3,) or not np.all(np.isfinite(off)):
                raise InputError(f"body shape {off_name} must be 3 finite numbers (mm), got {off.tolist()}", source)
        if not (np.isfinite(self.foot_pitch) and abs(self.foot_pitch) < np.pi / 2):
            raise InputError(f"body shape foot_pitch must be within (-pi/2, pi/2) radians, got {self.foot_pitch}",
                             source)
        return self

    def to_dict(self) -> dict:
        return {
            "lengths": {k: float(v) for k, v in self.lengths.items()},
            "radius_proximal": {k: float(v) for k, v in self.radius_proximal.items()},
            "radius_distal": {k: float(v) for k, v in self.radius_distal.items()},
            "depth_scale": {k: float(v) for k, v in self.depth_scale.items()},
            "left_hip_offset": [float(x) for x in self.left_hip_offset],
            "right_hip_offset": [float(x) for x in self.right_hip_offset],
            "left_shoulder_offset": [float(x) for x in self.left_shoulder_offset],
            "right_shoulder_offset": [float(x) for x in self.right_shoulder_offset],
            "abdomen_offset": [float(x) for x in self.abdomen_offset],
            "foot_pitch": float(self.foot_pitch),
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, d: dict, source: str | None = None) -> "BodyShape":
        try:
            shape = cls(
                lengths=dict(d["lengths"]), radius_proximal=dict(d["radius_proximal"]),
                radius_distal=dict(d["radius_distal"]), depth_scale=dict(d["depth_scale"]),
                left_hip_offset=tuple(d["left_hip_offset"]), right_hip_offset=tuple(d["right_hip_offset"]),
                left_shoulder_offset=tuple(d["left_shoulder_offset"]),
                right_shoulder_offset=tuple(d["right_shoulder_offset"]),
                abdomen_offset=tuple(d.get("abdomen_offset", (0.0, 0.0, 0.0))),
                foot_pitch=float(d.get("foot_pitch", 0.3)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"not a valid body shape ({type(exc).__name__}: {exc})", source) from None
        return shape.validate(source)

    @classmethod
    def from_json(cls, text: str, source: str | None = None) -> "BodyShape":
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"body shape is not valid JSON: {exc}", source) from None
        return cls.from_dict(d, source)

    def scaled_radii(self, factor: float) -> "BodyShape":
        """A copy with every radius multiplied by ``factor`` (lengths unchanged)."""
        return BodyShape(
            lengths=dict(self.lengths),
            radius_proximal={k: v * factor for k, v in self.radius_proximal.items()},
            radius_distal={k: v * factor for k, v in self.radius_distal.items()},
            depth_scale=dict(self.depth_scale),
            left_hip_offset=self.left_hip_offset, right_hip_offset=self.right_hip_offset,
            left_shoulder_offset=self.left_shoulder_offset, right_shoulder_offset=self.right_shoulder_offset,
            abdomen_offset=self.abdomen_offset, foot_pitch=self.foot_pitch,
        )


#: Stature of the default shape (mm).
DEFAULT_STATURE = 1750.0


def default_shape() -> BodyShape:
    """An adult of 1.75 m.

    Segment lengths follow Winter's anthropometric proportions of stature H
    (Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., 2009,
    Fig. 4.1): thigh 0.245 H, shank 0.246 H, upper arm 0.186 H, forearm 0.146 H;
    hip joint at 0.530 H, shoulder at 0.818 H. Radii are typical adult
    girths / (2 pi) rounded to 5 mm.
    """
    lengths = {
        "pelvis": 90.0, "torso": 480.0, "head": 260.0,
        "left_upper_arm": 325.0, "left_lower_arm": 255.0, "left_hand": 150.0,
        "right_upper_arm": 325.0, "right_lower_arm": 255.0, "right_hand": 150.0,
        "left_upper_leg": 430.0, "left_lower_leg": 430.0, "left_foot": 160.0,
        "right_upper_leg": 430.0, "right_lower_leg": 430.0, "right_foot": 160.0,
    }
    r_prox = {"pelvis": 155.0, "torso": 140.0, "head": 70.0, "upper_arm": 50.0, "lower_arm": 42.0, "hand": 40.0,
              "upper_leg": 85.0, "lower_leg": 55.0, "foot": 45.0}
    r_dist = {"pelvis": 150.0, "torso": 165.0, "head": 85.0, "upper_arm": 42.0, "lower_arm": 30.0, "hand": 35.0,
              "upper_leg": 55.0, "lower_leg": 38.0, "foot": 35.0}
    depth = {"pelvis": 0.65, "torso": 0.6, "head": 1.1, "upper_arm": 0.9, "lower_arm": 0.8, "hand": 0.45,
             "upper_leg": 0.95, "lower_leg": 0.9, "foot": 0.6}

    def per_segment(table: dict[str, float]) -> dict[str, float]:
        out = {}
        for s in SEGMENT_NAMES:
            key = s.replace("left_", "").replace("right_", "")
            out[s] = table[key]
        return out

    return BodyShape(
        lengths=lengths, radius_proximal=per_segment(r_prox), radius_distal=per_segment(r_dist),
        depth_scale=per_segment(depth),
        left_hip_offset=(0.0, 90.0, -80.0), right_hip_offset=(0.0, -90.0, -80.0),
        left_shoulder_offset=(0.0, 180.0, -60.0), right_shoulder_offset=(0.0, -180.0, -60.0),
        abdomen_offset=(0.0, 0.0, 0.0), foot_pitch=0.3,
    ).validate()


def scaled_shape(shape: BodyShape, factor: float) -> BodyShape:
    """``shape`` with every length, offset and radius multiplied by ``factor``."""
    def times(table: dict[str, float]) -> dict[str, float]:
        return {k: v * factor for k, v in table.items()}

    def vec(v: tuple[float, float, float]) -> tuple[float, float, float]:
        return tuple(float(x) * factor for x in v)

    return replace(shape, lengths=times(shape.lengths), radius_proximal=times(shape.radius_proximal),
                   radius_distal=times(shape.radius_distal), left_hip_offset=vec(shape.left_hip_offset),
                   right_hip_offset=vec(shape.right_hip_offset), left_shoulder_offset=vec(shape.left_shoulder_offset),
                   right_shoulder_offset=vec(shape.right_shoulder_offset), abdomen_offset=vec(shape.abdomen_offset))


def fifteen_cone_model(shape: BodyShape | None = None) -> BodyModel:
    """The 15-segment, 40-dof body model of Taylor (2009) for a given shape (default adult if None).

    Links (17): pelvis (root), torso (abdomen joint), head, per arm a clavicle
    frame, upper arm, lower arm, hand; per leg upper leg, lower leg, foot. The
    clavicle frames carry no cone: their 2 dof move the shoulder joint about the
    thorax point.
    """
    shape = (shape or default_shape()).validate()
    L = shape.lengths
    down = (0.0, 0.0, -1.0)
    up = (0.0, 0.0, 1.0)
    links: list[Link] = []

    def add(name, parent, offset, joint, dofs=(), axes=()):
        links.append(Link(name, parent, tuple(float(x) for x in offset), joint, tuple(dofs), tuple(axes)))
        return len(links) - 1

    pelvis = add("pelvis", -1, (0, 0, 0), FREE, _dofs("root", 6))
    torso = add("torso", pelvis, shape.abdomen_offset, BALL, _dofs("abdomen", 3))
    head = add("head", torso, (0, 0, L["torso"]), BALL, _dofs("head", 3))
    arm_links = {}
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        clav = add(f"{side}_clavicle", torso, (0, 0, L["torso"]), EULER, _dofs(f"{side}_clavicle", 2),
                   ((sgn, 0.0, 0.0), (0.0, 0.0, -sgn)))
        ua = add(f"{side}_upper_arm", clav, getattr(shape, f"{side}_shoulder_offset"), BALL,
                 _dofs(f"{side}_shoulder", 3))
        la = add(f"{side}_lower_arm", ua, (0, 0, -L[f"{side}_upper_arm"]), EULER, _dofs(f"{side}_elbow", 2),
                 ((0.0, -1.0, 0.0), (0.0, 0.0, sgn)))
        hand = add(f"{side}_hand", la, (0, 0, -L[f"{side}_lower_arm"]), EULER, _dofs(f"{side}_wrist", 1),
                   ((-sgn, 0.0, 0.0),))
        arm_links[side] = (ua, la, hand)
    leg_links = {}
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        ul = add(f"{side}_upper_leg", pelvis, getattr(shape, f"{side}_hip_offset"), BALL, _dofs(f"{side}_hip", 3))
        ll = add(f"{side}_lower_leg", ul, (0, 0, -L[f"{side}_upper_leg"]), EULER, _dofs(f"{side}_knee", 2),
                 ((0.0, 1.0, 0.0), (0.0, 0.0, sgn)))
        foot = add(f"{side}_foot", ll, (0, 0, -L[f"{side}_lower_leg"]), EULER, _dofs(f"{side}_ankle", 1),
                   ((0.0, 1.0, 0.0),))
        leg_links[side] = (ul, ll, foot)

    fp = shape.foot_pitch
    foot_axis = (float(np.cos(fp)), 0.0, float(-np.sin(fp)))
    seg_link_axis = {
        "pelvis": (pelvis, down), "torso": (torso, up), "head": (head, up),
    }
    for side in ("left", "right"):
        ua, la, hand = arm_links[side]
        ul, ll, foot = leg_links[side]
        seg_link_axis.update({
            f"{side}_upper_arm": (ua, down), f"{side}_lower_arm": (la, down), f"{side}_hand": (hand, down),
            f"{side}_upper_leg": (ul, down), f"{side}_lower_leg": (ll, down), f"{side}_foot": (foot, foot_axis),
        })
    segments = [
        Segment(s, seg_link_axis[s][0], seg_link_axis[s][1], float(L[s]), float(shape.radius_proximal[s]),
                float(shape.radius_distal[s]), float(shape.depth_scale[s]))
        for s in SEGMENT_NAMES
    ]

    def seg_end(s: str) -> tuple[float, float, float]:
        link, axis = seg_link_axis[s]
        return tuple(L[s] * np.asarray(axis))

    points = [
        NamedPoint("pelvis", pelvis, (0, 0, 0)),
        NamedPoint("thorax", torso, (0, 0, L["torso"])),
        NamedPoint("head", head, seg_end("head")),
    ]
    for side in ("left", "right"):
        ua, la, hand = arm_links[side]
        points += [NamedPoint(f"{side}_shoulder", ua, (0, 0, 0)), NamedPoint(f"{side}_elbow", la, (0, 0, 0)),
                   NamedPoint(f"{side}_wrist", hand, (0, 0, 0))]
    for side in ("left", "right"):
        ul, ll, foot = leg_links[side]
        points += [NamedPoint(f"{side}_hip", ul, (0, 0, 0)), NamedPoint(f"{side}_knee", ll, (0, 0, 0)),
                   NamedPoint(f"{side}_ankle", foot, (0, 0, 0))]
    for side in ("left", "right"):
        points.append(NamedPoint(f"{side}_hand_end", arm_links[side][2], seg_end(f"{side}_hand")))
    for side in ("left", "right"):
        points.append(NamedPoint(f"{side}_toe", leg_links[side][2], seg_end(f"{side}_foot")))

    lower = np.array([lo for _, lo, _ in DOF_LAYOUT])
    upper = np.array([hi for _, _, hi in DOF_LAYOUT])
    # Root height that puts the lowest point of the feet (ankle or toe end of the
    # foot cone, minus the cone's depth radius) at z = 0 in the rest pose.
    lows = []
    for side in ("left", "right"):
        foot = f"{side}_foot"
        ankle_z = getattr(shape, f"{side}_hip_offset")[2] - L[f"{side}_upper_leg"] - L[f"{side}_lower_leg"]
        depth = shape.depth_scale[foot]
        lows.append(ankle_z - shape.radius_proximal[foot] * depth)
        lows.append(ankle_z - L[foot] * np.sin(fp) - shape.radius_distal[foot] * depth)
    rest_height = -min(lows)
    return BodyModel(
        name="15-cone", links=links, segments=segments, points=points, dof_names=list(DOF_NAMES),
        lower=lower, upper=upper, marker_names=list(MARKER_NAMES), shape=shape, rest_root_height=rest_height,
    )


def stance_pose(model: BodyModel, abduction: float) -> np.ndarray:
    """The rest pose of the 15-cone ``model`` with both arms raised sideways by ``abduction`` (rad)."""
    pose = model.rest_pose()
    pose[model.dof_index("left_shoulder_x")] = abduction
    pose[model.dof_index("right_shoulder_x")] = -abduction
    return pose
