"""The pose step the CRBM family shares: a model that draws the next frame's features, plus parts.

A :class:`ConditionalPrior` is a :class:`~priors.learned.LearnedPrior` whose model reads each particle's last
poses as invariant features (:mod:`tracker.core.representation`): its parts (:mod:`priors.parts`) move them into
the frame the model knows (a posture offset, a root-height offset), it normalises them, the parts put further
inputs in front (the particle's pace, where the model takes one), and the model draws the next frame's normalised
features (:meth:`ConditionalPrior.draw`, the one method a member of the family implements). The prediction goes
back through the same parts, the root is integrated from the pending step, and the ground diffusion is added. The
CRBM, the FCRBM, the deep CRBM and the neural priors are this step with their own model.
"""
from __future__ import annotations

from abc import abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from priors.common import torch_generator
from priors.learned import LearnedPrior, PartSpec, is_paced, resolve_parts
from priors.parts import GroundDiffusion, GrowingModels, HeightOffset, PaceInput, Part, PostureOffset, Step
from tracker.core.errors import InputError
from tracker.core.representation import STEP_FEATURES, pending_step, poses_to_invariant
from tracker.engine.prior import PriorState

if TYPE_CHECKING:  # torch loads when a prior is built, not when the priors register
    import torch


#: The parts of the CRBM family, in the order a step runs them: the pace (exactly when the models take a pace
#: input), the root-height offset and the posture offset (both off by default), the ground diffusion.
CONDITIONAL_PARTS = (PartSpec("pace", PaceInput, paced=True), PartSpec("height", HeightOffset),
                     PartSpec("posture", PostureOffset), PartSpec("ground", GroundDiffusion))


class ConditionalPrior(LearnedPrior):
    """Samples every particle's next pose from its own history with a model of the CRBM family, in one batch.

    ``models`` are the models of increasing order (:class:`~priors.parts.GrowingModels`; each has ``order``,
    ``normaliser``, ``pose_step_rms`` and, when trained with a pace input, ``pace_input(log_paces)``). The parts
    are those the prior declares (:attr:`PARTS`; by default :data:`CONDITIONAL_PARTS`), each given as a keyword
    under its name (``ground=GroundDiffusion(0.0)``; None or absent: from ``options``, the registered builder's
    option values, else its default for the models; :func:`~priors.learned.resolve_parts`). Per-particle state:
    ``step`` ``P x 3``, the pending root step (:data:`~tracker.core.representation.STEP_FEATURES`) of the newest
    history frame, which the previous sample chose, and the parts' own entries. Each sample's torch generator is
    seeded from the filter's generator.
    """

    PARTS: ClassVar[tuple[PartSpec, ...]] = CONDITIONAL_PARTS

    def __init__(self, models: GrowingModels, *, device: str | torch.device = "cpu",
                 options: Mapping[str, Any] | None = None, **parts: Part | None):
        import torch

        paced = is_paced(models.first)
        if any(is_paced(m) != paced for m in models):
            raise InputError(f"{models.kind} models for one prior must all have a pace input or none")
        super().__init__(resolve_parts(self.PARTS, paced=paced, options=options, given=parts, kind=models.kind))
        self.models = models
        self.device = torch.device(device)
        self.order = models.order

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
        return {"orders": [m.order for m in self.models], **super().settings()}

    def diffusion_std(self) -> np.ndarray:
        return self.models.models[-1].pose_step_rms

    def model_state(self, known: np.ndarray, n_particles: int) -> PriorState:
        """The pending step of the last known frame (:func:`~tracker.core.representation.pending_step`). Refuses
        known frames too few for every model (a higher order never runs on a padded history)."""
        self.model_for(min(len(known), self.order))
        return {"step": np.repeat(pending_step(known)[None], n_particles, axis=0)}

    def model_noise(self, n_particles: int, available: int, rng: np.random.Generator) -> torch.Generator:
        """The torch generator of the model's draw, seeded by one draw from ``rng``."""
        return torch_generator(rng, self.device)

    def adopt(self, state: PriorState, history: np.ndarray, available: int,
              rng: np.random.Generator) -> PriorState:
        """The state of particles arriving from another motion model: the step out of each one's own newest pose;
        the pace, height and posture offsets those positions held (slow quantities of the person, not of one
        pose)."""
        return {**state, "step": pending_step(history[:, history.shape[1] - min(available, 2):])}

    def prepare(self, history: np.ndarray, available: int, state: PriorState) -> Step:
        model = self.model_for(available)
        n = model.order
        feats = poses_to_invariant(history[:, -n - 1:] if history.shape[1] > n else
                                   np.concatenate([history[:, :1], history], axis=1))[:, -n:]
        feats[:, -1, list(STEP_FEATURES)] = state["step"]
        # the newest frame's features with the step the particle takes
        return Step(previous=feats[:, -1].copy(), history=feats, model=model)

    def predict(self, step: Step, state: PriorState, noise: torch.Generator) -> np.ndarray:
        import torch

        model = step.model
        z = model.normaliser.transform(step.history).reshape(len(step.history), -1)  # P x (n K)
        z = np.concatenate([*step.inputs, z], axis=1) if step.inputs else z
        conditioning = torch.tensor(z, dtype=torch.float32, device=self.device)
        v = self.draw(model, conditioning, noise, state)
        return model.normaliser.inverse(v.cpu().double().numpy())
