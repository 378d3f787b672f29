"""Clips that change activity: one retargeted clip cross-faded into another (e.g. a walk into a run of the same
subject) in the body-centred invariant representation (:mod:`tracker.core.representation`).

The output is the first clip up to ``switch_at - fade``, then ``fade`` frames whose invariant features (root
velocities, height, pitch, roll, yaw rate and joint angles) blend linearly from the first clip into the second,
then the second clip. Poses are integrated from the first clip's first frame, so the ground path continues
smoothly. The second clip enters at the frame whose joint angles are nearest the first clip's at the start of
the fade (``second_start="match"``, the default), so the legs are in the same phase of the gait. The result uses
the first clip's body model; its ground-truth markers are the body model's markers at the blended poses (the
mocap's own joints do not exist for blended frames).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from data_tools.motion.retarget import RetargetResult
from tracker.core.errors import InputError
from tracker.core.kinematics import markers as model_markers
from tracker.core.representation import N_ROOT, invariant_to_poses, poses_to_invariant, start_of


@dataclass(frozen=True)
class Transition:
    """Where the activity changes in a cross-faded clip: the fade covers frames ``fade_start .. switch - 1``;
    ``second_start`` is the frame of the second clip that enters at ``fade_start``."""

    fade_start: int
    switch: int
    second_start: int


def matching_frame(first_features: np.ndarray, second_features: np.ndarray, usable: int) -> int:
    """The frame among the first ``usable`` of ``second_features`` ``T2 x D`` whose joint angles are nearest
    (Euclidean, radians) to ``first_features`` ``(D,)``."""
    d = np.linalg.norm(second_features[:usable, N_ROOT:] - first_features[N_ROOT:], axis=-1)
    return int(np.argmin(d))


def cross_fade(first: RetargetResult, second: RetargetResult, switch_at: int, fade: int = 12,
               second_start: int | str = "match") -> tuple[RetargetResult, Transition]:
    """``first`` until frame ``switch_at``, then ``second``, the invariant features cross-faded over the ``fade``
    frames before ``switch_at`` (see the module docstring). ``second_start`` is the second clip's frame that
    enters at the fade's start, or ``"match"``. Both clips must share the pose layout and frame rate."""
    if first.model.dof_names != second.model.dof_names:
        raise InputError("the two clips of a transition have different pose layouts", second.source)
    if abs(first.fps - second.fps) > 1e-6:
        raise InputError(f"the two clips of a transition have different frame rates ({first.fps:g} and "
                         f"{second.fps:g} Hz)", second.source)
    if isinstance(fade, bool) or not isinstance(fade, (int, np.integer)) or fade < 1:
        raise InputError(f"fade must be a whole number of frames of at least 1, got {fade!r}")
    if isinstance(switch_at, bool) or not isinstance(switch_at, (int, np.integer)) \
            or not fade < switch_at < len(first.poses):
        raise InputError(f"switch_at must be a frame in {fade + 1}..{len(first.poses) - 1} (after the fade of "
                         f"{fade} frames, within the first clip's {len(first.poses)} frames), got {switch_at!r}",
                         first.source)
    fa, fb = poses_to_invariant(first.poses)[:-1], poses_to_invariant(second.poses)[:-1]
    s0 = switch_at - fade
    if len(fb) <= fade + 1:
        raise InputError(f"the second clip has {len(second.poses)} frames; a fade of {fade} needs more", second.source)
    if second_start == "match":
        second_start = matching_frame(fa[s0], fb, max(1, min(len(fb) - fade - 1, len(fb) // 2)))
    elif isinstance(second_start, bool) or not isinstance(second_start, (int, np.integer)) \
            or not 0 <= second_start < len(fb) - fade:
        raise InputError(f"second_start must be 'match' or a frame in 0..{len(fb) - fade - 1}, got {second_start!r}",
                         second.source)
    fb = fb[second_start:]
    w = (np.arange(1, fade + 1) / (fade + 1))[:, None]
    blended = np.concatenate([fa[:s0], (1 - w) * fa[s0:switch_at] + w * fb[:fade], fb[fade:]])
    xy, yaw = start_of(first.poses)
    poses = invariant_to_poses(blended, xy, yaw, first.poses[0, 3:6])
    marks = model_markers(first.model, poses)
    source = f"{first.source} -> {second.source} (fade {fade} frames before frame {switch_at})"
    clip = RetargetResult(model=first.model, poses=poses, markers=marks, model_markers=marks, fps=first.fps,
                          source=source)
    return clip, Transition(s0, int(switch_at), int(second_start))
