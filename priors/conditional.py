"""The pose step the CRBM family shares: a model that draws the next frame's features, plus parts.

A :class:`ConditionalPrior` turns each particle's last poses into invariant features
(:mod:`tracker.core.representation`), lets its parts (:mod:`priors.parts`) move them into the frame the model
knows (a posture offset, a root-height offset), normalises them, puts the particle's pace in front where the
model takes one, and asks its model for the next frame's normalised features (:meth:`ConditionalPrior.draw`,
the one method a member of the family implements). The prediction goes back through the same parts, the root is
integrated from the pending step, and the ground diffusion is added. The CRBM, the FCRBM and the deep CRBM
priors are this step with their own model.
"""
from __future__ import annotations

from abc import abstractmethod
from typing import TYPE_CHECKING, Any

import numpy as np

from priors.common import torch_generator
from priors.parts import GroundDiffusion, GrowingModels, HeightOffset, PaceInput, PostureOffset, shift_height
from tracker.core.errors import InputError
from tracker.core.representation import STEP_FEATURES, next_poses, pending_step, posture_features, poses_to_invariant
from tracker.engine.prior import MotionPrior, PriorState

if TYPE_CHECKING:  # torch loads when a prior is built, not when the priors register
    import torch


class ConditionalPrior(MotionPrior):
    """Samples every particle's next pose from its own history with a model of the CRBM family, in one batch.

    ``models`` are the models of increasing order (:class:`~priors.parts.GrowingModels`; each has ``order``,
    ``normaliser``, ``pose_step_rms`` and, when trained with a pace input, ``pace_input(log_paces)``). The parts:
    ``ground`` (always), ``pace`` (exactly when the models take a pace input), ``height`` and ``posture``
    (None: off). Per-particle state: ``step`` ``P x 3``, the pending root step
    (:data:`~tracker.core.representation.STEP_FEATURES`) of the newest history frame, which the previous sample
    chose, and the parts' own entries. Each sample's torch generator is seeded from the filter's generator.
    """

    def __init__(self, models: GrowingModels, *, device: str | torch.device = "cpu",
                 ground: GroundDiffusion = GroundDiffusion(), pace: PaceInput | None = None,
                 height: HeightOffset | None = None, posture: PostureOffset | None = None):
        import torch

        paced = getattr(models.first, "pace_label", None) is not None
        if any((getattr(m, "pace_label", None) is not None) != paced for m in models):
            raise InputError(f"{models.kind} models for one prior must all have a pace input or none")
        if pace is not None and not paced:
            raise InputError(f"the pace settings are for a {models.kind} trained with a pace input (train "
                             "--pace-input); this one has none")
        self.models = models
        self.device = torch.device(device)
        self.ground = ground
        self.pace = None if not paced else PaceInput() if pace is None else pace
        self.height = height if height is not None and height.active else None
        self.posture = posture if posture is not None and posture.gain > 0 else None
        self.order = models.order
        self.summary_names = tuple(p.SUMMARY for p in self.parts if hasattr(p, "SUMMARY"))
        if self.summary_names:  # posterior means of the parts' quantities
            self.summary_kind = "quantity"

    @property
    def parts(self) -> list[Any]:
        """The parts in use, in the order their state is started and summarised."""
        return [p for p in (self.ground, self.pace, self.height, self.posture) if p is not None]

    @abstractmethod
    def draw(self, model: Any, conditioning: torch.Tensor, generator: torch.Generator,
             state: PriorState) -> torch.Tensor:
        """The next frames' normalised features ``P x K`` that ``model`` draws for the conditioning inputs
        ``P x (C + N K)`` (the pace when the model takes one, then the history, oldest first), with every random
        number from ``generator``; ``state`` is the particles' state (a style label, for instance)."""

    def model_for(self, available: int) -> Any:
        """The model that draws the next frame when ``available`` history slots are real poses."""
        return self.models.model_for(available)

    def label_for(self, available: int) -> str:
        return f"{self.name} order {self.model_for(available).order}"

    def settings(self) -> dict:
        out = {"orders": [m.order for m in self.models]}
        for part in self.parts:
            out.update(part.settings())
        return out

    def diffusion_std(self) -> np.ndarray:
        return self.models.models[-1].pose_step_rms

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        """The pending step of the last known frame (:func:`~tracker.core.representation.pending_step`) and the
        parts' states. Refuses known frames too few for every model (a higher order never runs on a padded
        history)."""
        known = np.atleast_2d(known)
        self.model_for(min(len(known), self.order))
        step = pending_step(known)
        state = {"step": np.repeat(step[None], n_particles, axis=0)}
        if self.pace is not None:
            state.update(self.pace.start(step, n_particles, rng))
        if self.posture is not None:
            state.update(self.posture.start(known.shape[-1], n_particles))
        if self.height is not None:
            state.update(self.height.start(n_particles, rng))
        return state

    def restart(self, state: PriorState, recent: np.ndarray, n_particles: int,
                rng: np.random.Generator) -> PriorState:
        """:meth:`start` from ``recent``, keeping the posture offset (it is the person's, not the lost frame's)."""
        new = self.start(recent, n_particles, rng)
        return new if self.posture is None else self.posture.restart(state, new, n_particles)

    def adopt(self, state: PriorState, history: np.ndarray, available: int,
              rng: np.random.Generator) -> PriorState:
        """The state of particles arriving from another motion model: the step out of each one's own newest pose;
        the pace, height and posture offsets those positions held (slow quantities of the person, not of one
        pose)."""
        return {**state, "step": pending_step(history[:, history.shape[1] - min(available, 2):])}

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        model = self.model_for(available)
        n = model.order
        step = list(STEP_FEATURES)
        feats = poses_to_invariant(history[:, -n - 1:] if history.shape[1] > n else
                                   np.concatenate([history[:, :1], history], axis=1))[:, -n:]
        feats[:, -1, step] = state["step"]
        previous = feats[:, -1].copy()  # the newest frame's features with the step the particle takes
        new: dict[str, np.ndarray] = {}
        posture = posture_features(feats.shape[-1])
        offset = None
        if self.posture is not None:  # the history in the postures the model knows
            offset = self.posture.updated(state, previous[:, posture])
            feats[:, :, posture] -= offset
        height = None
        if self.height is not None:  # the history at the heights the model knows
            height = new["height_offset"] = self.height.advance(state["height_offset"], rng)
            shift_height(feats, -height)
        z = model.normaliser.transform(feats).reshape(len(feats), -1)  # P x (n K)
        if self.pace is not None:  # the model is told each particle's pace, which drifts first
            pace = new["pace"] = self.pace.advance(state["pace"], rng)
            z = np.concatenate([model.pace_input(pace), z], axis=1)
        import torch

        conditioning = torch.tensor(z, dtype=torch.float32, device=self.device)
        v = self.draw(model, conditioning, torch_generator(rng, self.device), state)
        f_next = model.normaliser.inverse(v.cpu().double().numpy())
        if offset is not None:  # and the prediction in the person's posture and height
            f_next[:, posture] += offset
            new.update(PostureOffset.state(offset, f_next[:, posture], len(f_next)))
        if height is not None:
            shift_height(f_next, height)
        poses = next_poses(history[:, -1], previous, f_next)
        self.ground.apply(poses, rng)
        new["step"] = f_next[:, step]
        return poses, new

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray | None:
        """The posterior means of :attr:`summary_names` (the pace, the height offset, the posture offset's RMS);
        None when no part has one."""
        values = [p.summarize(state, weights) for p in self.parts if hasattr(p, "SUMMARY")]
        return np.array(values) if values else None
