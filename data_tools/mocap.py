"""Motion capture clips as joint positions: the common result of every mocap reader.

Convention: world frame z up (mocap in y up is rotated on load by
:data:`Y_UP_TO_Z_UP`), millimetres, frames on the leading axis. A clip keeps
the positions of all its skeleton's points; :func:`marker_positions` picks the
15 HumanEva-style markers (and the extra points retargeting fits) by the
skeleton's naming convention.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from data_tools.checks import MAX_FPS, MIN_FPS, check_range
from tracker.core.body import EXTRA_POINT_NAMES, MARKER_NAMES
from tracker.core.errors import InputError

#: Rotation taking y-up mocap coordinates to our z-up world: (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

MM_PER_INCH = 25.4


@dataclass
class MocapClip:
    """A mocap clip as positions of named skeleton points.

    ``positions`` ``T x J x 3`` (mm, z up), ``point_names`` J names (ASF: bone
    ends, named by bone, plus ``root``; BVH: joint origins by joint name plus
    ``<joint>_end`` for end sites), ``fps`` frames per second, ``style``
    ``'asf'`` or ``'bvh'`` (selects the marker naming table).
    """

    path: str
    positions: np.ndarray
    point_names: list[str]
    fps: float
    style: str
    notes: list[str] = field(default_factory=list)

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]



def _name_index(names: list[str]) -> dict[str, int]:
    return {n.lower(): i for i, n in enumerate(names)}


def check_fps(fps: float, what: str = "frame rate", source: str | None = None) -> float:
    """``fps`` as a float, refused unless a number in [:data:`~data_tools.checks.MIN_FPS`,
    :data:`~data_tools.checks.MAX_FPS`] Hz."""
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number, got {fps!r}", source) from None
    return float(check_range(fps, what, source, lo=MIN_FPS, hi=MAX_FPS, unit=" Hz"))


def resample(clip: MocapClip, fps: float) -> MocapClip:
    """The clip at ``fps`` frames per second.

    When the source rate is an integer multiple of ``fps`` (120 -> 60 or 30 Hz)
    every k-th frame is kept, as in Taylor (2009). Otherwise positions are
    interpolated linearly in time (a small, documented loss of rigidity).
    Upsampling is refused: it invents motion that was never measured.
    """
    fps = check_fps(fps, "target frame rate")
    if fps > clip.fps * (1 + 1e-9):
        raise InputError(f"cannot resample from {clip.fps:g} Hz up to {fps:g} Hz; choose a rate <= {clip.fps:g}",
                         clip.path)
    ratio = clip.fps / fps
    if abs(ratio - round(ratio)) < 1e-6:
        k = int(round(ratio))
        pos = clip.positions[::k]
    else:
        t_src = np.arange(clip.n_frames) / clip.fps
        t_new = np.arange(0.0, t_src[-1] + 1e-12, 1.0 / fps)
        flat = clip.positions.reshape(clip.n_frames, -1)
        pos = np.stack([np.interp(t_new, t_src, flat[:, j]) for j in range(flat.shape[1])], axis=1)
        pos = pos.reshape(len(t_new), *clip.positions.shape[1:])
    return MocapClip(clip.path, pos, list(clip.point_names), fps, clip.style, list(clip.notes))


# Candidate point names per role, in order of preference (case-insensitive).
# ASF points are bone *ends*: 'lhumerus' is the elbow. BVH points are joint
# origins: 'LeftElbow' / 'lForeArm' is the elbow. '@mid:a,b' is the midpoint.
_ASF_ROLES = {
    "pelvis": ["root"], "thorax": ["thorax"], "head": ["head"],
    "left_shoulder": ["lclavicle"], "left_elbow": ["lhumerus"], "left_wrist": ["lradius"],
    "right_shoulder": ["rclavicle"], "right_elbow": ["rhumerus"], "right_wrist": ["rradius"],
    "left_hip": ["lhipjoint"], "left_knee": ["lfemur"], "left_ankle": ["ltibia"],
    "right_hip": ["rhipjoint"], "right_knee": ["rfemur"], "right_ankle": ["rtibia"],
    "left_hand_end": ["lhand"], "right_hand_end": ["rhand"], "left_toe": ["lfoot"], "right_toe": ["rfoot"],
}


def _bvh_side(template: dict[str, list[str]]) -> dict[str, list[str]]:
    out = {}
    for role, names in template.items():
        if role.startswith("SIDE_"):
            for side, long, short in (("left", "Left", "l"), ("right", "Right", "r")):
                out[role.replace("SIDE", side)] = [n.replace("LONG", long).replace("SHORT", short) for n in names]
        else:
            out[role] = names
    return out


# Two BVH naming families appear in CMU conversions: "Hips/LeftHip/LeftKnee"
# and "hip/lThigh/lShin" (Poser style). When the head chain ends in eye joints
# rather than an end site, the head marker is the midpoint between the eyes.
_BVH_ROLES = _bvh_side({
    "pelvis": ["@root"], "thorax": ["lowerneck", "neck"], "head": ["head_end", "@mid:lefteye,righteye"],
    "SIDE_shoulder": ["LONGShoulder", "SHORTShldr"], "SIDE_elbow": ["LONGElbow", "SHORTForeArm"],
    "SIDE_wrist": ["LONGWrist", "SHORTHand"], "SIDE_hip": ["LONGHip", "LONGUpLeg", "SHORTThigh"],
    "SIDE_knee": ["LONGKnee", "LONGLeg", "SHORTShin"], "SIDE_ankle": ["LONGAnkle", "LONGFoot", "SHORTFoot"],
    "SIDE_hand_end": ["SHORTFingers", "SHORTMid1", "LONGHand_end", "SHORThand_end"],
    "SIDE_toe": ["LONGToe", "LONGToeBase", "SHORTFoot_end"],
})


def marker_positions(clip: MocapClip, roles=MARKER_NAMES + EXTRA_POINT_NAMES) -> np.ndarray:
    """Positions ``T x M x 3`` (mm) of the named roles (default: 15 markers then the 4 extra fit points).

    Raises :class:`InputError` naming the clip's file and the roles that its
    skeleton does not provide.
    """
    table = _ASF_ROLES if clip.style == "asf" else _BVH_ROLES
    idx = _name_index(clip.point_names)
    out = np.empty((clip.n_frames, len(roles), 3))
    missing = []
    for m, role in enumerate(roles):
        found = None
        for cand in table[role]:
            if cand == "@root":
                found = clip.positions[:, 0, :]
            elif cand.startswith("@mid:"):
                a, b = cand[5:].split(",")
                if a in idx and b in idx:
                    found = 0.5 * (clip.positions[:, idx[a]] + clip.positions[:, idx[b]])
            elif cand.lower() in idx:
                found = clip.positions[:, idx[cand.lower()]]
            if found is not None:
                break
        if found is None:
            missing.append(f"{role} (looked for {', '.join(table[role])})")
        else:
            out[:, m] = found
    if missing:
        raise InputError("skeleton lacks points for: " + "; ".join(missing), clip.path)
    return out
