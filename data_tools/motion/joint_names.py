"""The skeleton naming conventions recognised in mocap files, as data.

Each convention says, for every point the body model needs (the 15 markers of
:data:`tracker.core.body.MARKER_NAMES`, the hand ends and toes of
:data:`~tracker.core.body.EXTRA_POINT_NAMES`, and the head joint that a missing
head end is derived from), which of a file's points is that point: a list of
candidate names, the first one present wins. Names are matched case-insensitively
and after dropping a namespace (``mixamorig:Hips`` is ``Hips``). ``SIDE`` in a
role stands for ``left`` and ``right``; in a name, ``{Side}`` for ``Left`` and
``Right`` and ``{s}`` for ``l`` and ``r``. A name ``@root`` is the file's root
joint; a list inside the list (``["leftEye", "rightEye"]``) is the midpoint of
those points. BVH points are joint origins, named by their joint, and End Sites,
named ``<joint>_end``; ASF points are bone ends, named by their bone.

:mod:`data_tools.motion.skeleton_points` reads these tables; a file whose names none of
them covers is mapped with a joint map (``--joint-map``).
"""
from __future__ import annotations

#: Where a convention's names are found: ``"bvh"`` (joint origins and End Sites) or ``"asf"`` (bone ends).
BVH, ASF = "bvh", "asf"

#: The point a missing head end is derived from: the origin of the head joint (the top of the neck).
HEAD_JOINT = "head_joint"

#: The name shown for the ``_L``/``_R`` game-rig convention of Bandai Namco Research's datasets.
BANDAI = "Bandai Namco (UpperArm_L, game rig)"


def _sided(table: dict[str, list]) -> dict[str, tuple]:
    """Expand ``SIDE_`` roles and ``{Side}`` / ``{s}`` names into left and right entries."""
    def name(n, long: str, short: str):
        if isinstance(n, list):
            return tuple(name(m, long, short) for m in n)
        return n.replace("{Side}", long).replace("{s}", short)

    out: dict[str, tuple] = {}
    for role, names in table.items():
        if role.startswith("SIDE_"):
            for side, long, short in (("left", "Left", "l"), ("right", "Right", "r")):
                out[role.replace("SIDE", side)] = tuple(name(n, long, short) for n in names)
        else:
            out[role] = tuple(name(n, "", "") for n in names)
    return out


#: Conventions in the order they are tried; each is (name shown to users, where its names are, table).
#: When several cover a file, the one that finds the most points (markers first) wins.
CONVENTIONS: tuple[tuple[str, str, dict[str, tuple]], ...] = (
    # CMU's Acclaim skeletons: points are bone ends ('lhumerus' ends at the elbow).
    ("CMU ASF", ASF, _sided({
        "pelvis": ["root"], "thorax": ["thorax"], "head": ["head"], HEAD_JOINT: ["upperneck"],
        "SIDE_shoulder": ["{s}clavicle"], "SIDE_elbow": ["{s}humerus"], "SIDE_wrist": ["{s}radius"],
        "SIDE_hip": ["{s}hipjoint"], "SIDE_knee": ["{s}femur"], "SIDE_ankle": ["{s}tibia"],
        "SIDE_hand_end": ["{s}hand"], "SIDE_toe": ["{s}foot"],
    })),
    # A BVH whose joints carry the ASF bone names: a joint sits where its bone starts ('lhumerus' at the
    # shoulder).
    ("ASF bone", BVH, _sided({
        "pelvis": ["@root"], "thorax": ["lowerneck"], "head": ["head_end"], HEAD_JOINT: ["head"],
        "SIDE_shoulder": ["{s}humerus"], "SIDE_elbow": ["{s}radius"], "SIDE_wrist": ["{s}wrist"],
        "SIDE_hip": ["{s}femur"], "SIDE_knee": ["{s}tibia"], "SIDE_ankle": ["{s}foot"],
        "SIDE_hand_end": ["{s}fingers", "{s}hand_end"], "SIDE_toe": ["{s}toes", "{s}foot_end"],
    })),
    # MotionBuilder / HumanIK names: Mixamo (namespace mixamorig:), Ubisoft's LAFAN1, the SFU database,
    # CMU's MotionBuilder-friendly export (LHipJoint, LeftFingerBase, Neck1).
    ("MotionBuilder (Mixamo, LAFAN1, SFU)", BVH, _sided({
        "pelvis": ["@root"], "thorax": ["Neck"], "head": ["HeadTop_End", "Head_end"], HEAD_JOINT: ["Head"],
        "SIDE_shoulder": ["{Side}Arm"], "SIDE_elbow": ["{Side}ForeArm"], "SIDE_wrist": ["{Side}Hand"],
        "SIDE_hip": ["{Side}UpLeg"], "SIDE_knee": ["{Side}Leg"], "SIDE_ankle": ["{Side}Foot"],
        "SIDE_hand_end": ["{Side}HandMiddle1", "{Side}HandIndex1", "{Side}FingerBase", "{Side}Hand_end"],
        "SIDE_toe": ["{Side}ToeBase", "{Side}Toe", "{Side}Foot_end"],
    })),
    # Biovision's names, as MocapBank and CMU's "Hips/LeftHip/Chest2" export use them (the latter adds
    # lowerneck, LFingers).
    ("Biovision (MocapBank)", BVH, _sided({
        "pelvis": ["@root"], "thorax": ["lowerneck", "Neck"], "head": ["Head_end"], HEAD_JOINT: ["Head"],
        "SIDE_shoulder": ["{Side}Shoulder"], "SIDE_elbow": ["{Side}Elbow"], "SIDE_wrist": ["{Side}Wrist"],
        "SIDE_hip": ["{Side}Hip"], "SIDE_knee": ["{Side}Knee"], "SIDE_ankle": ["{Side}Ankle"],
        "SIDE_hand_end": ["{s}Fingers", "{Side}Fingers", "{Side}Wrist_end"],
        "SIDE_toe": ["{Side}Toe", "{Side}Ankle_end"],
    })),
    # Poser / DAZ names, as CMU's "hip/abdomen/chest" export uses them; the head ends in two eye joints.
    ("Poser (DAZ)", BVH, _sided({
        "pelvis": ["@root"], "thorax": ["neck"], "head": ["head_end", ["leftEye", "rightEye"]],
        HEAD_JOINT: ["head"],
        "SIDE_shoulder": ["{s}Shldr"], "SIDE_elbow": ["{s}ForeArm"], "SIDE_wrist": ["{s}Hand"],
        "SIDE_hip": ["{s}Thigh"], "SIDE_knee": ["{s}Shin"], "SIDE_ankle": ["{s}Foot"],
        "SIDE_hand_end": ["{s}Mid1", "{s}Hand_end"], "SIDE_toe": ["{s}Toe", "{s}Foot_end"],
    })),
    # Game-rig names with an _L/_R suffix, as in Bandai Namco Research's motion datasets: an extra root
    # (joint_Root) on the ground below Hips, a short neck (Neck at its base, Head a few cm up) and End Sites
    # that coincide with their joints, so the head end and the hand ends are derived.
    (BANDAI, BVH, _sided({
        "pelvis": ["Hips"], "thorax": ["Neck"], HEAD_JOINT: ["Head"],
        "SIDE_shoulder": ["UpperArm_{s}"], "SIDE_elbow": ["LowerArm_{s}"], "SIDE_wrist": ["Hand_{s}"],
        "SIDE_hip": ["UpperLeg_{s}"], "SIDE_knee": ["LowerLeg_{s}"], "SIDE_ankle": ["Foot_{s}"],
        "SIDE_toe": ["Toes_{s}"],
    })),
)

# Points derived when a file lacks them, from the proportions of the shared CMU skeletons: medians over
# 02_01, 02_03, 07_01, 07_02, 09_01, 16_15, 49_18 and 91_straight_walk (both sides), in the ASF conversion.

#: The direction from the ankle to the toe in the body's frame (x forward, y toward the body's own side,
#: z up along the spine; the frame of the hip line and the pelvis-to-thorax line), unit length.
FOOT_DIRECTION = (0.933, 0.020, -0.360)
#: Ankle-to-toe length over knee-to-ankle length.
FOOT_PER_SHANK = 0.285
#: Wrist-to-hand-end length over elbow-to-wrist length; the hand end continues the forearm's line.
HAND_PER_FOREARM = 0.66
#: Head-joint-to-head-end length over thorax-to-head-joint length; the head end continues that line.
HEAD_PER_NECK = 0.51
#: Thorax-to-head-end length over pelvis-to-thorax length (0.66 to 0.95 over the same skeletons), for
#: conventions whose head joint sits low on a short neck (:data:`HEAD_BY_TORSO`), where continuing the neck
#: by :data:`HEAD_PER_NECK` would end the head a few cm above the neck: the head end lies on the
#: thorax-to-head-joint line, this far from the thorax.
HEAD_PER_TORSO = 0.77
#: Conventions whose missing head end is placed by :data:`HEAD_PER_TORSO` rather than :data:`HEAD_PER_NECK`.
HEAD_BY_TORSO = (BANDAI,)
