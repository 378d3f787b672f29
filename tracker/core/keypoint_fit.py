"""Poses fitted to 2-D keypoints: the 40 pose numbers that project the body's keypoints onto a detector's.

:func:`fit_pose` minimises, over a batch of starting poses at once, the robust reprojection cost of the body
keypoints (:data:`tracker.core.keypoints.KEYPOINTS`) in every view::

    cost = sum over views and keypoints of  c * log(1 + |projection - detection|^2 / s^2)  +  prior * |angles|^2

a Cauchy (Lorentzian) loss weighted by the detector's confidence ``c``, so that a wrong detection pulls little;
``s`` is the keypoint's spread (:data:`tracker.core.keypoints.KEYPOINT_SPREAD_MM`) seen at its depth in
pixels. Each view's left and right arms, legs and ears are scored both as labelled and swapped (plus
:data:`SWAP_COST`), the cheaper counting: a detector's swap does not twist the fit, and a body turned round,
every group swapped, costs more than the person facing the way they do. The small ``prior`` on the joint angles
(radians, not the root) keeps the numbers no keypoint constrains (a forearm's twist) near rest. The optimiser is
torch's Adam with the step shrinking over the iterations; after every step the angles are put back within the
joint limits, so the result always respects them.

With two or more views the keypoints fix the pose; with one, the body's size fixes its depth (the start must
say roughly where the person is). Shapes: detections ``V x K x 3`` (pixels, confidence), poses ``B x D``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from tracker.core.body import BodyModel
from tracker.core.cameras import CameraRig
from tracker.core.keypoints import KEYPOINT_SPREAD_MM, KEYPOINTS, keypoint_table, swap_group_indices, swap_permutation
from tracker.core.torch_kinematics import torch_kinematics

#: Confidence below which a detection takes no part in a fit.
MIN_CONFIDENCE = 0.3
#: What reading one view's left/right group the other way round costs (the keypoint likelihood's log odds of a
#: swap, log(0.95 / 0.05)): a swap in one view is absorbed, a body turned round (every group swapped in every
#: view) is not mistaken for the person.
SWAP_COST = 3.0


@dataclass
class Fitted:
    """Fitted poses ``B x D`` (one per start, within the joint limits), their costs ``(B,)`` and the index of
    the cheapest."""

    poses: np.ndarray
    costs: np.ndarray

    @property
    def best(self) -> int:
        return int(np.argmin(self.costs))

    @property
    def pose(self) -> np.ndarray:
        """The cheapest fitted pose ``(D,)``."""
        return self.poses[self.best]


class KeypointCost:
    """The fit's cost (module docstring) of poses ``B x D`` against one frame's ``detections`` ``V x K x 3`` in
    the views of ``rig``, as a torch function (float64 on the CPU)."""

    def __init__(self, model: BodyModel, rig: CameraRig, detections: np.ndarray, prior: float = 0.05):
        self.model, self.rig, self.prior = model, rig, prior
        self.kinematics = torch_kinematics(model, "cpu", torch.float64)
        links, offsets = keypoint_table(model)
        self.links = torch.as_tensor(links)
        self.offsets = torch.as_tensor(offsets)
        detections = np.asarray(detections, float)
        conf = np.where(detections[..., 2] >= MIN_CONFIDENCE, detections[..., 2], 0.0)
        self.conf = torch.as_tensor(conf)  # V x K
        self.observed = torch.as_tensor(np.nan_to_num(detections[..., :2]))  # V x K x 2
        self.R = torch.as_tensor(rig.R)
        self.t = torch.as_tensor(rig.t)
        self.focal = torch.as_tensor(rig.focal.mean(axis=1))  # V
        self.spread = torch.as_tensor([KEYPOINT_SPREAD_MM[k] for k in KEYPOINTS])  # K
        self.swapped = torch.as_tensor(swap_permutation())
        self.groups = [torch.as_tensor(np.sort(np.r_[left, right])) for left, right in swap_group_indices()]
        grouped = np.concatenate([g.numpy() for g in self.groups])
        self.single = torch.as_tensor(np.setdiff1d(np.arange(len(KEYPOINTS)), grouped))
        self.angles = torch.as_tensor(np.r_[np.zeros(6, bool), np.ones(model.n_dofs - 6, bool)])

    def keypoints(self, poses: torch.Tensor) -> torch.Tensor:
        """Body keypoints ``B x K x 3`` (mm) of poses ``B x D``."""
        R, o = self.kinematics.links(poses)
        return torch.einsum("bkij,kj->bki", R[:, self.links], self.offsets) + o[:, self.links]

    def per_keypoint(self, poses: torch.Tensor) -> torch.Tensor:
        """Each keypoint's loss ``B x V x K`` against the detections as labelled and ``B x V x K`` swapped."""
        X = self.keypoints(poses)
        Xc = torch.einsum("vij,bkj->vbki", self.R, X) + self.t[:, None, None, :]  # V x B x K x 3
        z = Xc[..., 2].clamp_min(1.0)
        u, v = self.rig.pixels(Xc[..., 0], Xc[..., 1], z)
        pixels = torch.stack([u, v], dim=-1).transpose(0, 1)  # B x V x K x 2
        s = (self.focal[:, None, None] * self.spread / z).transpose(0, 1).detach().clamp_min(1.5)  # B x V x K

        def loss(order: torch.Tensor) -> torch.Tensor:
            r2 = ((pixels - self.observed[:, order]) ** 2).sum(-1)
            return self.conf[:, order] * torch.log1p(r2 / s ** 2)

        return loss(torch.arange(len(KEYPOINTS))), loss(self.swapped)

    def __call__(self, poses: torch.Tensor) -> torch.Tensor:
        """Costs ``(B,)`` of poses ``B x D``."""
        straight, crossed = self.per_keypoint(poses)
        total = straight[..., self.single].sum(dim=(-1, -2))
        for members in self.groups:
            a = straight[..., members].sum(-1)
            b = crossed[..., members].sum(-1)
            total = total + torch.minimum(a, b + SWAP_COST).sum(-1)
        return total + self.prior * (poses[:, self.angles] ** 2).sum(-1)


def fit_pose(model: BodyModel, rig: CameraRig, detections: np.ndarray, starts: np.ndarray, iterations: int = 250,
             step: float = 0.05, prior: float = 0.05) -> Fitted:
    """Fit every start pose ``B x D`` to one frame's ``detections`` ``V x K x 3`` in the views of ``rig``
    (module docstring): ``iterations`` Adam steps of ``step`` radians (root position: ``step`` metres),
    shrinking to a tenth along a cosine."""
    cost = KeypointCost(model, rig, detections, prior)
    starts = model.clip_to_limits(np.atleast_2d(np.asarray(starts, float)))
    scale = torch.ones(model.n_dofs, dtype=torch.float64)
    scale[:3] = 1000.0  # position in metres inside the optimiser: one step size for all numbers
    x = (torch.as_tensor(starts) / scale).requires_grad_(True)
    optimiser = torch.optim.Adam([x], lr=step)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, iterations, eta_min=step / 10)
    lower = torch.as_tensor(model.lower) / scale
    upper = torch.as_tensor(model.upper) / scale
    for _ in range(iterations):
        optimiser.zero_grad()
        cost(x * scale).sum().backward()
        optimiser.step()
        schedule.step()
        with torch.no_grad():
            x.copy_(torch.maximum(torch.minimum(x, upper), lower))
    with torch.no_grad():
        poses = (x * scale).numpy().copy()
        costs = cost(x * scale).numpy().copy()
    return Fitted(model.clip_to_limits(poses), costs)
