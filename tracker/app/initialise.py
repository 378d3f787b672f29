"""The body's size and first pose from the first frame's silhouettes, for sequences without ground truth.

A global search, then a local one, both scored by the tracker's own likelihood (so the start is what the filter
would rate best):

1. where: the rays through each view's silhouette centroid meet (least squares) near the person's centre; the
   pelvis is placed above that point at the standing height of the scaled body;
2. a grid over the floor position (``±`` :data:`POSITION_SPAN` mm around that point), the heading (every
   :data:`HEADING_STEP` degrees), the body's scale (:data:`SCALES`, lengths, offsets and radii alike) and the
   stance (standing with arms down, A-pose, T-pose: :data:`STANCES`); or, with ``near``, one approximate pose
   of the user's instead of the stances;
3. for the best grid poses and for each of them turned by 180 degrees (silhouettes hardly tell front from back,
   so both headings are refined and the likelihood decides), a narrowing random search over one group of pose
   numbers at a time (:data:`BLOCKS`: the root, the trunk, each arm, each leg).

Measured on the real four-camera T-pose example (272 x 480 views, seeds 0 to 2), the group-wise search of step 3
reaches log-likelihoods of -29.0 to -30.5 where one search over all 40 numbers at once reached -34.6 to -45.9
(and once ended facing backwards).

The result is a pose ``(D,)`` of the fitted body model and its :class:`~tracker.core.body.BodyShape`.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from tracker.core.body import (BodyModel, BodyShape, default_shape, fifteen_cone_model, scaled_shape,
                               stance_pose)
from tracker.core.cameras import CameraRig
from tracker.core.errors import InputError
from tracker.core.kinematics import markers, standing_height

POSITION_SPAN = 400.0
POSITION_STEP = 100.0
HEADING_STEP = 15.0
SCALES = (0.88, 0.94, 1.0, 1.06, 1.12)
#: Grid poses kept per scale and stance, and how many of all those kept are refined.
KEEP, REFINE = 3, 8
#: Pose numbers refined together, by the start of their names (the root, the trunk, each limb).
BLOCKS = {"root": ("root_",), "trunk": ("abdomen_", "head_"),
          "left arm": ("left_clavicle", "left_shoulder", "left_elbow", "left_wrist"),
          "right arm": ("right_clavicle", "right_shoulder", "right_elbow", "right_wrist"),
          "left leg": ("left_hip", "left_knee", "left_ankle"), "right leg": ("right_hip", "right_knee", "right_ankle")}
#: Shoulder abduction (radians) of each stance.
STANCES = {"standing": 0.15, "a-pose": np.pi / 4, "t-pose": np.pi / 2 * 0.95}


@dataclass
class Initialisation:
    """A first pose ``(D,)`` (mm, rad), the fitted shape, its model, the stance chosen, the scale, the
    log-likelihood of the pose and the standing height of the fitted body (mm)."""

    pose: np.ndarray
    shape: BodyShape
    model: BodyModel
    stance: str
    scale: float
    score: float
    height: float


def silhouette_centre(rig: CameraRig, masks: list[np.ndarray]) -> np.ndarray:
    """The world point (mm) nearest, in least squares, to the rays through every mask's centroid."""
    A, b = np.zeros((3, 3)), np.zeros(3)
    for cam, mask in zip(rig.cameras, masks):
        ys, xs = np.nonzero(mask)
        if len(xs) == 0:
            continue
        K = np.array([[cam.fx, cam.skew * cam.fx, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
        xy = cv2.undistortPoints(np.array([[[xs.mean(), ys.mean()]]]), K, np.asarray(cam.dist))[0, 0]
        d = cam.R.T @ np.array([xy[0], xy[1], 1.0])
        d /= np.linalg.norm(d)
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ cam.centre
    if np.linalg.matrix_rank(A) < 3:
        raise InputError("the silhouettes of fewer than two cameras show the person: cannot place the body")
    return np.linalg.solve(A, b)


def initialise(seq, frame: int = 0, *, near: np.ndarray | None = None, seed: int = 0, rounds: int = 12,
               samples: int = 200, likelihood: str = "edge-silhouette",
               shape: BodyShape | None = None) -> Initialisation:
    """Fit the body's scale and first pose to the silhouettes of ``frame`` of ``seq`` (module docstring).

    ``near``: an approximate first pose ``(D,)`` of the default model to search around instead of the stances
    (its position and heading are searched too). ``shape``: the person's measured body shape (for example
    :func:`data_tools.vision.landmarks.shape_from_landmarks`), kept as it is (scale 1) instead of searching the
    default adult's scale. The sequence needs silhouettes (``masks/``) or plates.
    """
    from tracker.app.plugins import likelihood_entry
    from tracker.app.threads import configured_threads
    from tracker.engine.registry import LikelihoodContext, resolve_options

    rng = np.random.default_rng(seed)
    fr = seq.frame(frame, range(seq.n_views))
    masks = list(fr.masks) if fr.masks is not None else None
    if masks is None:
        from likelihoods.observations import silhouette

        masks = [silhouette(img, bg) for img, bg in zip(fr.images, fr.backgrounds)]
    centre = silhouette_centre(seq.rig, masks)
    entry = likelihood_entry(likelihood)
    options = resolve_options(f"likelihood {likelihood}", entry.options, {})
    base = default_shape() if shape is None else shape
    starts = {"near": np.asarray(near, float)} if near is not None else None
    offsets = np.arange(-POSITION_SPAN, POSITION_SPAN + 1e-9, POSITION_STEP)
    headings = np.radians(np.arange(0.0, 360.0, HEADING_STEP))
    candidates = []  # (log-likelihood, scale, stance, pose, model, shape, scorer)
    for scale in (SCALES if shape is None else (1.0,)):
        body = scaled_shape(base, scale)
        model = fifteen_cone_model(body)
        score = entry.build(LikelihoodContext(model, seq.rig, "cpu", configured_threads()), options).prepare(fr)
        templates = starts or {name: stance_pose(model, a) for name, a in STANCES.items()}
        for name, template in templates.items():
            grid = np.tile(template, (len(offsets) ** 2 * len(headings), 1))
            dx, dy, h = np.meshgrid(offsets, offsets, headings, indexing="ij")
            grid[:, 0] = centre[0] + dx.ravel()
            grid[:, 1] = centre[1] + dy.ravel()
            grid[:, 2] = model.rest_root_height
            grid[:, 3:6] = 0.0
            grid[:, 5] = h.ravel()
            values = score(grid)
            for k in np.argsort(values)[::-1][:KEEP]:
                candidates.append((float(values[k]), scale, name, grid[k].copy(), model, body, score))
    candidates.sort(key=lambda c: -c[0])
    # Both headings of the best few, then the limbs, group by group; the best pose kept.
    refined = []
    for value, scale, name, pose, model, body, score in candidates[:REFINE]:
        turned = pose.copy()
        turned[5] += np.pi
        for start in (pose, turned):
            found, found_value = refine_pose(score, model, start, float(score(start[None])[0]), rng, rounds, samples)
            refined.append((found_value, scale, name, found, model, body))
    value, scale, name, pose, model, body = max(refined, key=lambda c: c[0])
    return Initialisation(pose, body, model, name, scale, value, standing_height(model))


def refine_pose(score, model: BodyModel, pose: np.ndarray, value: float, rng: np.random.Generator, rounds: int,
                samples: int) -> tuple[np.ndarray, float]:
    """A narrowing random search from ``pose`` ``(D,)`` (log-likelihood ``value`` under ``score``, which maps
    ``P x D`` poses to ``(P,)``): in each of ``rounds`` rounds, for each group of :data:`BLOCKS` in turn,
    ``samples`` Gaussian steps of that group alone (80 mm and 0.25 rad at first, shrinking by 0.8 a round), the best kept when it scores higher. Returns the pose and its log-likelihood."""
    step = np.full(model.n_dofs, 0.25)
    step[:3] = 80.0
    groups = [np.array([i for i, n in enumerate(model.dof_names) if n.startswith(starts)])
              for starts in BLOCKS.values()]
    for _ in range(rounds):
        for idx in groups:
            trial = np.tile(pose, (samples, 1))
            trial[:, idx] += rng.normal(size=(samples, len(idx))) * step[idx]
            trial = model.clip_to_limits(trial)
            values = score(trial)
            k = int(np.argmax(values))
            if values[k] > value:
                value, pose = float(values[k]), trial[k]
        step *= 0.8
    return pose, value


def limb_lengths(model: BodyModel, pose: np.ndarray) -> dict[str, float]:
    """Lengths (mm) of the fitted body's segments between markers: upper arm, forearm, thigh, shank (left)."""
    m = markers(model, pose[None])[0]
    idx = {n: i for i, n in enumerate(model.marker_names)}

    def dist(a: str, b: str) -> float:
        return float(np.linalg.norm(m[idx[a]] - m[idx[b]]))

    return {"upper arm": dist("left_shoulder", "left_elbow"), "forearm": dist("left_elbow", "left_wrist"),
            "thigh": dist("left_hip", "left_knee"), "shank": dist("left_knee", "left_ankle")}
