"""Keypoint layouts of common 2-D detectors, each mapped to the body model's keypoints.

A layout is the detector's list of points in its output order. :data:`LAYOUTS` maps each to the body model's
:data:`tracker.core.keypoints.KEYPOINTS`; points without a counterpart (eyes, heels, small toes, the
OpenPose ``MidHip``) are left out. :func:`to_canonical` reorders a detector's output into that set.

========================  ==========================================================================
layout                    used by
========================  ==========================================================================
``body_25``               OpenPose's default BODY_25 model
``body_25b``              OpenPose's experimental BODY_25B (Pose2Sim's default; it has a ``Head`` top)
``coco_17``               COCO keypoints: MMPose/RTMPose, YOLO-pose, Detectron2, Sports2D's ``coco``
``halpe_26``              HALPE 26: AlphaPose, RTMPose ``body26`` (Pose2Sim's and Sports2D's RTMPose default)
``blazepose_33``          MediaPipe BlazePose's 33 landmarks
========================  ==========================================================================

Where a detector's point lies on the body differs from the model's joint centres (a detector's hip is
lower and further out than the hip joint's centre); :data:`tracker.core.keypoints.KEYPOINT_SPREAD_MM` states
the spread the likelihood allows for each.
"""
from __future__ import annotations

import numpy as np

from tracker.core.errors import InputError
from tracker.core.keypoints import KEYPOINT_INDEX, KEYPOINTS

_LIMBS_OPENPOSE = {
    "LShoulder": "left_shoulder", "LElbow": "left_elbow", "LWrist": "left_wrist",
    "RShoulder": "right_shoulder", "RElbow": "right_elbow", "RWrist": "right_wrist",
    "LHip": "left_hip", "LKnee": "left_knee", "LAnkle": "left_ankle",
    "RHip": "right_hip", "RKnee": "right_knee", "RAnkle": "right_ankle",
    "Nose": "nose", "LEar": "left_ear", "REar": "right_ear", "LBigToe": "left_toe", "RBigToe": "right_toe",
}

#: Each layout's point names, in the detector's output order.
LAYOUT_NAMES: dict[str, tuple[str, ...]] = {
    "body_25": ("Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "MidHip",
                "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar",
                "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel"),
    "body_25b": ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow", "RElbow", "LWrist",
                 "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle", "Neck", "Head", "LBigToe",
                 "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel"),
    "coco_17": ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow", "RElbow", "LWrist",
                "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle"),
    "halpe_26": ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow", "RElbow", "LWrist",
                 "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle", "Head", "Neck", "Hip",
                 "LBigToe", "RBigToe", "LSmallToe", "RSmallToe", "LHeel", "RHeel"),
    "blazepose_33": ("nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye",
                     "right_eye_outer", "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder",
                     "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_pinky",
                     "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb", "left_hip",
                     "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel",
                     "right_heel", "left_foot_index", "right_foot_index"),
}

#: Each layout's point name -> the body model's keypoint it is (:data:`tracker.core.keypoints.KEYPOINTS`).
LAYOUTS: dict[str, dict[str, str]] = {
    "body_25": {**_LIMBS_OPENPOSE, "Neck": "neck"},
    "body_25b": {**_LIMBS_OPENPOSE, "Neck": "neck", "Head": "head_top"},
    "coco_17": {k: v for k, v in _LIMBS_OPENPOSE.items() if "Toe" not in k},
    "halpe_26": {**_LIMBS_OPENPOSE, "Neck": "neck", "Head": "head_top"},
    "blazepose_33": {**{name: name for name in KEYPOINTS if name in LAYOUT_NAMES["blazepose_33"]},
                     "left_foot_index": "left_toe", "right_foot_index": "right_toe"},
}


def layout_index(layout: str) -> np.ndarray:
    """For each body keypoint, its index in ``layout``'s output ``(K,)``, -1 where the layout lacks it; an
    :class:`InputError` names the known layouts for an unknown one."""
    if layout not in LAYOUTS:
        raise InputError(f"unknown keypoint layout {layout!r} (known: {', '.join(LAYOUTS)})")
    names = LAYOUT_NAMES[layout]
    index = np.full(len(KEYPOINTS), -1)
    for name, keypoint in LAYOUTS[layout].items():
        index[KEYPOINT_INDEX[keypoint]] = names.index(name)
    return index


def to_canonical(points: np.ndarray, layout: str) -> np.ndarray:
    """A detector's output ``(..., J, 3)`` (pixel x, y, confidence; J the layout's length) as the body
    keypoints ``(..., K, 3)``: keypoints the layout lacks get NaN pixels and confidence 0."""
    points = np.asarray(points, dtype=float)
    names = LAYOUT_NAMES.get(layout)
    index = layout_index(layout)
    if points.shape[-2:] != (len(names), 3):
        raise InputError(f"a {layout} detection has {len(names)} points of 3 numbers (x, y, confidence), got "
                         f"shape {points.shape[-2:]}")
    out = np.full(points.shape[:-2] + (len(KEYPOINTS), 3), np.nan)
    out[..., 2] = 0.0
    have = index >= 0
    out[..., have, :] = points[..., index[have], :]
    return out
