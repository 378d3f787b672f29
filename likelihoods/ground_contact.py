"""Ground contact: the depth one camera cannot see, from the floor it can.

A body slid along one camera's ray keeps its silhouette nearly unchanged (400 mm of depth is about an 8% change
of scale) but sinks into the floor or floats above it, and its root rises or falls with the ray. This term scores
a pose by how far its lowest foot point (ankles and toes) and its root are from their heights in the known first
frames: ``-0.5 (d_foot / ground_std)^2 - 0.5 (d_root / root_height_std)^2`` (mm; a std of 0 leaves its part
out). It is added to the image likelihood (``edge-silhouette`` and ``keypoints+edge-silhouette`` take
``ground_std`` and ``root_height_std``), and it knows nothing of the images.

Measured with one camera (``docs/methods_report.md``, section 10; tuned on the learned-priors protocol's fold A,
run once on fold B), ``ground_std = 20`` and ``root_height_std = 60`` lower zero-velocity's marker error to 0.84
and 0.93 of what it was, the recommended mixture's from 1.08 to 0.96 and from 0.85 to 0.70 of zero-velocity's;
with four cameras it is a tie to a small loss (0.72 to 0.74). So it is on by default with one camera and off
with more (:func:`ground_contact_config`). It does not stop a learned prior's root from drifting along the ray at
the wrong walking speed, and it holds a jump down: track a person who leaves the floor with both spreads 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.core.body import BodyModel
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.registry import Option

#: The body points whose lowest is the foot on the floor (those of them a body model has: PARSEC's 10-cone model
#: has ankles and no toes).
FOOT_POINTS = ("left_ankle", "right_ankle", "left_toe", "right_toe")


def foot_points(model: BodyModel) -> list[int]:
    """Indices into ``model.points`` of the :data:`FOOT_POINTS` the model has (at least the ankles)."""
    names = {p.name for p in model.points}
    index = [model.point_index(name) for name in FOOT_POINTS if name in names]
    if not index:
        raise ValueError(f"the {model.name} body model has none of the foot points {', '.join(FOOT_POINTS)}")
    return index


def lowest_foot_height(model: BodyModel, poses: np.ndarray, feet: list[int] | None = None) -> np.ndarray:
    """Height (mm) ``(P,)`` of the lowest foot point (:data:`FOOT_POINTS`; ``feet``: their indices, as
    :func:`foot_points` gives them) of finite poses ``P x D``."""
    from tracker.core.kinematics import forward_kinematics

    feet = foot_points(model) if feet is None else feet
    return forward_kinematics(model, np.asarray(poses, float)).points[:, feet, 2].min(axis=1)


@dataclass(frozen=True)
class GroundContactConfig:
    """``ground_std`` and ``root_height_std`` (mm): the spreads of the lowest foot's and of the root's height
    about the known frames'; 0 leaves that part out."""

    ground_std: float = 0.0
    root_height_std: float = 0.0

    @property
    def active(self) -> bool:
        return self.ground_std > 0 or self.root_height_std > 0


#: The spreads (mm) used with one camera unless given: the setting tuned on fold A and confirmed on fold B.
ONE_VIEW_GROUND_STD, ONE_VIEW_ROOT_HEIGHT_STD = 20.0, 60.0
#: The term's options, declared once: those of the likelihoods it joins (``edge-silhouette``,
#: ``keypoints+edge-silhouette``) and of ``capture``. None: the default for the number of tracked cameras.
GROUND_OPTIONS: tuple[Option, ...] = (
    Option("ground_std", float, None, "ground contact: spread of the lowest foot's height about the known frames' "
           "(likelihoods.ground_contact); 0 leaves the feet out (both 0: no ground contact, as for a person who "
           "jumps)", minimum=0.0, maximum=1e6, unit="mm",
           default_note=f"{ONE_VIEW_GROUND_STD:g} mm with one camera, 0 with more"),
    Option("root_height_std", float, None, "ground contact: spread of the root's height about the known frames'; "
           "0 leaves the root out", minimum=0.0, maximum=1e6, unit="mm",
           default_note=f"{ONE_VIEW_ROOT_HEIGHT_STD:g} mm with one camera, 0 with more"),
)


def ground_contact_config(views: int, ground_std: float | None = None,
                          root_height_std: float | None = None) -> GroundContactConfig:
    """The ground contact for ``views`` tracked cameras: the spreads given, or where one is None, the one-camera
    defaults (:data:`ONE_VIEW_GROUND_STD`, :data:`ONE_VIEW_ROOT_HEIGHT_STD`) with one camera and 0 (off) with
    more."""
    def given_or_default(value: float | None, one_view: float) -> float:
        return (one_view if views == 1 else 0.0) if value is None else float(value)

    return GroundContactConfig(ground_std=given_or_default(ground_std, ONE_VIEW_GROUND_STD),
                               root_height_std=given_or_default(root_height_std, ONE_VIEW_ROOT_HEIGHT_STD))


class GroundContact(Likelihood):
    """The ground-contact term of the module's text, for the body ``model``. Its reference heights come from the
    known poses (:meth:`start`); before that, from the rest pose (feet on the floor z = 0)."""

    name = "ground-contact"

    def __init__(self, model: BodyModel, config: GroundContactConfig):
        self.model, self.config = model, config
        self.feet, self.root_height = foot_points(model), model.links[0].dofs[2]  # indices, found once
        rest = model.rest_pose()[None]
        self.foot_reference = float(lowest_foot_height(model, rest, self.feet)[0])
        self.root_reference = float(model.rest_root_height)

    def start(self, known: np.ndarray) -> None:
        known = np.atleast_2d(np.asarray(known, float))
        self.foot_reference = float(lowest_foot_height(self.model, known, self.feet).mean())
        self.root_reference = float(known[:, self.root_height].mean())

    def prepare(self, frame: Frame) -> FrameLikelihood:
        return _GroundFrame(self)

    def settings(self) -> dict:
        return {"ground_std": self.config.ground_std, "root_height_std": self.config.root_height_std}

    def log_likelihood(self, poses: np.ndarray) -> np.ndarray:
        """The term ``(P,)`` of poses ``P x D`` (numpy); a pose that is not finite gets 0 (the image terms give it
        -inf)."""
        poses = np.asarray(poses, float)
        out = np.zeros(len(poses))
        ok = np.all(np.isfinite(poses), axis=1)
        if not ok.any():
            return out
        if self.config.ground_std > 0:
            d = lowest_foot_height(self.model, poses[ok], self.feet) - self.foot_reference
            out[ok] -= 0.5 * (d / self.config.ground_std) ** 2
        if self.config.root_height_std > 0:
            d = poses[ok, self.root_height] - self.root_reference
            out[ok] -= 0.5 * (d / self.config.root_height_std) ** 2
        return out


class _GroundFrame(FrameLikelihood):
    """The term for one frame (it does not depend on the frame); poses on a torch device are scored on the CPU
    and returned on their device."""

    def __init__(self, term: GroundContact):
        self.term = term

    def __call__(self, poses):
        if hasattr(poses, "cpu"):  # a torch tensor
            import torch

            return torch.as_tensor(self.term.log_likelihood(poses.detach().cpu().numpy()), dtype=poses.dtype,
                                   device=poses.device)
        return self.term.log_likelihood(poses)
