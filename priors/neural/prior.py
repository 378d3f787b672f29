"""The neural motion prior: a mixture density network (:mod:`priors.neural.model`) draws each particle's next
frame from up to ``order`` history frames, plus the CRBM family's parts.

The pose step and the parts (ground diffusion, the pace where the model takes one, the root-height and posture
offsets) are :class:`priors.conditional.ConditionalPrior`'s, with the CRBM's defaults. One model draws from any
number of real history frames from one up to its order, so the history grows from the known frames without
lower-order models. Registered as the ``neural`` prior (``train`` and ``track --prior neural``).
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from priors.common import loaded, source_of
from priors.conditional import ConditionalPrior
from priors.crbm.prior import PACED_PARTS
from priors.learned import PartSpec, SmallModel, part_options
from priors.neural.settings import NEURAL_TRAIN_OPTIONS
from priors.parts import GrowingModels, Part, Step
from tracker.engine.prior import PriorState
from tracker.engine.registry import PriorContext, TrainingData, register_prior

if TYPE_CHECKING:  # the model and torch load when the prior is built or trained, not when it registers
    import torch

    from priors.neural.model import NeuralModel


class NeuralPrior(ConditionalPrior):
    """Samples every particle's next pose from its own last ``min(available, order)`` poses with a trained
    :class:`~priors.neural.model.NeuralModel`, in one batch. The parts are
    :class:`~priors.conditional.ConditionalPrior`'s, declared as the CRBM's
    (:data:`priors.crbm.prior.PACED_PARTS`): a part left unset takes the CRBM's default for a model with or
    without a pace input."""

    name = "neural"
    PARTS: ClassVar[tuple[PartSpec, ...]] = PACED_PARTS
    SMALL_MODELS: ClassVar[tuple[SmallModel, ...]] = (
        SmallModel({"order": 3, "hidden": 16, "layers": 1, "epochs": 2}),
        SmallModel({"order": 2, "hidden": 16, "layers": 1, "epochs": 2, "pace_input": True}, clips=3, label="paced"))

    def __init__(self, model: NeuralModel, *, device: str = "cpu", options: Mapping[str, Any] | None = None,
                 **parts: Part | None):
        super().__init__(GrowingModels([model], "neural prior"), device=device, options=options, **parts)
        self.model = model
        model.net.to(self.device).eval()

    def model_for(self, available: int) -> NeuralModel:
        """The one model, whatever the number of real history frames."""
        return self.model

    def label_for(self, available: int) -> str:
        return f"{self.name} ({min(max(available, 1), self.order)} of {self.order} frames)"

    def prepare(self, history: np.ndarray, available: int, state: PriorState) -> Step:
        """The step of :class:`~priors.conditional.ConditionalPrior`, the history cut to its real frames (at most
        the order)."""
        step = super().prepare(history, available, state)
        step.history = step.history[:, -min(max(available, 1), self.order):]
        return step

    def draw(self, model: NeuralModel, conditioning: torch.Tensor, generator: torch.Generator,
             state: PriorState) -> torch.Tensor:
        return model.net.sample(conditioning, generator)

    def settings(self) -> dict:
        c = self.model.config
        return {**super().settings(), "components": c.components, "hidden": c.hidden, "layers": c.layers}


def train_neural_from_data(data: TrainingData, options: dict, rng: np.random.Generator,
                           progress: Callable[[int, int, dict], None] | None = None, checkpoint: Path | None = None,
                           resume: bool = False) -> NeuralModel:
    """``train --prior neural``: :func:`priors.neural.training.train_neural_prior` (imported, with torch, when
    called)."""
    from priors.neural.training import train_neural_prior

    return train_neural_prior(data, options, rng, progress, checkpoint, resume)


@register_prior(
    "neural", summary="neural autoregressive prior: a mixture density network over an MLP encoding of the last "
                      "frames, drawing from one known frame on",
    model_files="one", train=train_neural_from_data, train_options=NEURAL_TRAIN_OPTIONS, resumable=True,
    options=part_options(NeuralPrior.PARTS))
def build_neural(context: PriorContext, model_files: Sequence[Path], options: dict) -> NeuralPrior:
    """The neural prior of one model file (or a trained model), checked against the sequence."""
    from priors.neural.file import load_neural
    from priors.neural.model import NeuralModel

    given = model_files[0]
    model = loaded(given, load_neural, NeuralModel, "neural prior", device=context.device)
    model.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps, source_of(given))
    return NeuralPrior(model, device=context.device, options=options)
