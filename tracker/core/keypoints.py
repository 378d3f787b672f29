"""The body model's keypoints: the points a 2-D keypoint detector marks, placed on the 15-cone model.

A detector (BlazePose, OpenPose, RTMPose, ...) marks joints and a few face points in each image. Every
layout's points are mapped to the one set :data:`KEYPOINTS` (``data_tools.vision.keypoints.layouts``), and each of
these lies at a fixed place on a link of the body model (:func:`keypoint_table`), so that a pose gives them
all by forward kinematics (:func:`keypoint_positions`):

=================  ==================================================================================
keypoint           place on the model (rest pose: the body faces +x, its left is +y, up is +z)
=================  ==================================================================================
``nose``           the head link, 0.62 of the head's length above the thorax point, ahead of the head's
                   axis by the head's mid depth radius plus 20 mm
``left_ear`` ...   the head link, 0.78 of the head's length above the thorax point, 0.4 of the mid depth
                   radius ahead of the axis and 0.75 of the mid width radius to each side
``neck``           the shoulder joints' midpoint at rest (OpenPose's ``Neck``)
``head_top``       the model's ``head`` point: the top of the head cone
shoulders ... ankles  the model's joint centres
``left_toe`` ...   the end of the foot cone (a detector's big toe or foot index)
=================  ==================================================================================

The face's points are placed where BlazePose puts them on a real person: on the real four-camera example
(``docs/guide/real_video.md``) the keypoints triangulated over the views lay, on average over the frames, 29 mm
above the nose's first placement (half the head's length) and 70 mm above, 32 mm ahead of and 18 mm inside the
ears' (half the head's length, on the head's axis, at its width radius), once the body was tracked to them;
these placements take that in (the only real footage they were measured on: the first frames of a person
standing still). A detector's joints are not joint centres either: on the same example, with these placements,
its hips lay 5 to 13 mm ahead of and 10 to 20 mm outside the tracked hip joints, its toes 27 to 30 mm ahead of
the foot cones' ends, its other joints within 18 mm (means over the frames). The keypoint likelihood allows for such
offsets with a spread per keypoint (:data:`KEYPOINT_SPREAD_MM`) rather than shifting the joints. Only the 15-cone
model has these points.

Left/right pairs (:data:`SWAP_GROUPS`) are what a detector mixes up: a view may label a whole arm, leg or
the ears the wrong way round.
"""
from __future__ import annotations

import numpy as np

from tracker.core.body import BodyModel
from tracker.core.errors import InputError

#: The keypoints every layout is mapped to, in this order.
KEYPOINTS = (
    "nose", "left_ear", "right_ear", "neck", "head_top",
    "left_shoulder", "left_elbow", "left_wrist",
    "right_shoulder", "right_elbow", "right_wrist",
    "left_hip", "left_knee", "left_ankle",
    "right_hip", "right_knee", "right_ankle",
    "left_toe", "right_toe",
)
KEYPOINT_INDEX = {name: i for i, name in enumerate(KEYPOINTS)}

#: How far (mm, one standard deviation in each direction) a detector's keypoint may lie from its place on the
#: model for a person whose pose the model matches: joint centres inside the flesh are marked on its surface
#: or, for hips and shoulders, where the detector's training data put them.
KEYPOINT_SPREAD_MM = {
    "nose": 40.0, "left_ear": 40.0, "right_ear": 40.0, "neck": 50.0, "head_top": 50.0,
    "left_shoulder": 40.0, "left_elbow": 30.0, "left_wrist": 30.0,
    "right_shoulder": 40.0, "right_elbow": 30.0, "right_wrist": 30.0,
    "left_hip": 50.0, "left_knee": 30.0, "left_ankle": 30.0,
    "right_hip": 50.0, "right_knee": 30.0, "right_ankle": 30.0,
    "left_toe": 40.0, "right_toe": 40.0,
}

#: Left/right groups a detector may swap as a whole in one view: the arms, the legs (feet included) and the ears.
SWAP_GROUPS = (
    (("left_shoulder", "left_elbow", "left_wrist"), ("right_shoulder", "right_elbow", "right_wrist")),
    (("left_hip", "left_knee", "left_ankle", "left_toe"), ("right_hip", "right_knee", "right_ankle", "right_toe")),
    (("left_ear",), ("right_ear",)),
)

#: The model's named points that are keypoints as they are.
_NAMED = {"head_top": "head", **{name: name for name in KEYPOINTS[5:]}}


def swap_group_indices() -> list[tuple[np.ndarray, np.ndarray]]:
    """Each of :data:`SWAP_GROUPS` as keypoint indices: ``(left (n,), right (n,))``, pairs in order."""
    return [(np.array([KEYPOINT_INDEX[n] for n in left]), np.array([KEYPOINT_INDEX[n] for n in right]))
            for left, right in SWAP_GROUPS]


def swap_permutation(groups: tuple[int, ...] = (0, 1, 2)) -> np.ndarray:
    """The keypoint order ``(K,)`` with the left and right sides of the :data:`SWAP_GROUPS` ``groups`` exchanged."""
    order = np.arange(len(KEYPOINTS))
    indices = swap_group_indices()
    for g in groups:
        left, right = indices[g]
        order[left], order[right] = right, left
    return order


def keypoint_table(model: BodyModel) -> tuple[np.ndarray, np.ndarray]:
    """Each keypoint's link ``(K,)`` (int) and position in that link's frame ``K x 3`` (mm), for the 15-cone
    ``model`` of any shape; an :class:`InputError` for a model without these links (PARSEC's 10 cones)."""
    cache = model._cache
    if "keypoint_table" in cache:
        return cache["keypoint_table"]
    names = [link.name for link in model.links]
    if "head" not in names or "torso" not in names or model.shape is None:
        raise InputError(f"the {model.name} body model has no keypoints: they are defined on the 15-cone model")
    shape = model.shape
    links = np.zeros(len(KEYPOINTS), int)
    offsets = np.zeros((len(KEYPOINTS), 3))
    for name, point in _NAMED.items():
        p = model.points[model.point_index(point)]
        links[KEYPOINT_INDEX[name]] = p.link
        offsets[KEYPOINT_INDEX[name]] = p.position
    head = names.index("head")
    length = shape.lengths["head"]
    radius = 0.5 * (shape.radius_proximal["head"] + shape.radius_distal["head"])
    depth = radius * shape.depth_scale["head"]
    for name, offset in (("nose", (depth + 20.0, 0.0, 0.62 * length)),
                         ("left_ear", (0.4 * depth, 0.75 * radius, 0.78 * length)),
                         ("right_ear", (0.4 * depth, -0.75 * radius, 0.78 * length))):
        links[KEYPOINT_INDEX[name]] = head
        offsets[KEYPOINT_INDEX[name]] = offset
    torso = names.index("torso")
    shoulders = 0.5 * (np.asarray(shape.left_shoulder_offset) + np.asarray(shape.right_shoulder_offset))
    links[KEYPOINT_INDEX["neck"]] = torso
    offsets[KEYPOINT_INDEX["neck"]] = np.array([0.0, 0.0, shape.lengths["torso"]]) + shoulders
    cache["keypoint_table"] = (links, offsets)
    return links, offsets


def keypoints_from_frames(model: BodyModel, rotations: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """The keypoints ``B x K x 3`` (mm) from link rotations ``B x L x 3 x 3`` and origins ``B x L x 3`` (world
    from link, mm: :class:`tracker.core.kinematics.Kinematics`)."""
    links, offsets = keypoint_table(model)
    return np.einsum("...kij,kj->...ki", rotations[..., links, :, :], offsets) + origins[..., links, :]


def keypoint_positions(model: BodyModel, poses: np.ndarray) -> np.ndarray:
    """The keypoints ``(..., K, 3)`` (mm, :data:`KEYPOINTS` order) of poses ``(..., D)``."""
    from tracker.core.kinematics import forward_kinematics

    fk = forward_kinematics(model, poses)
    return keypoints_from_frames(model, fk.rotations, fk.origins)
