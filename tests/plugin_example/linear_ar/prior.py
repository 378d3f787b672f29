# tests/plugin_example/linear_ar/prior.py
"""The ``linear-ar`` prior: each particle's next pose from a linear autoregressive model of its last pose's
normalised invariant features (:mod:`.model`), with the CRBM family's pose step and parts."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from priors.common import loaded, source_of
from priors.conditional import ConditionalPrior
from priors.learned import PartSpec, SmallModel, part_options
from priors.parts import GroundDiffusion, GrowingModels, HeightOffset, Part, PostureOffset
from tracker.engine.prior import PriorState
from tracker.engine.registry import Option, PriorContext, TrainingData, register_prior

if TYPE_CHECKING:  # torch and the model load when the prior is built or trained, not when it registers
    import torch

    from .model import LinearARModel

TRAIN_OPTIONS = (Option("ridge", float, 1e-3, "least-squares penalty on A", minimum=0.0, maximum=1e6),)  # train --ridge


class LinearARPrior(ConditionalPrior):
    name = "linear-ar"
    #: its parts, once, in the order a step runs them: a root-height offset of 30 mm by default, a posture offset
    #: (off by default), the ground diffusion
    PARTS: ClassVar[tuple[PartSpec, ...]] = (
        PartSpec("height", HeightOffset, defaults={"height_spread": 30.0}),
        PartSpec("posture", PostureOffset),
        PartSpec("ground", GroundDiffusion))
    #: models fitted in seconds on the first `clips` walks, which contract tests build the prior from
    SMALL_MODELS: ClassVar[tuple[SmallModel, ...]] = (SmallModel({"ridge": 1e-3}),)

    def __init__(self, model: LinearARModel, *, device: str = "cpu", options: Mapping[str, Any] | None = None,
                 **parts: Part | None):
        # parts: given as keywords (height=HeightOffset(0.0)), else from the registered options, else the defaults
        super().__init__(GrowingModels([model], "linear autoregressive"), device=device, options=options, **parts)

    def draw(self, model: LinearARModel, conditioning: torch.Tensor, generator: torch.Generator,
             state: PriorState) -> torch.Tensor:  # P x K -> P x K, every random number from generator
        import torch

        A, b, noise = (torch.as_tensor(v).to(conditioning) for v in (model.A, model.b, model.noise))
        z = torch.randn(conditioning.shape, generator=generator, dtype=conditioning.dtype, device=conditioning.device)
        return conditioning @ A.T + b + noise * z


def train_linear_ar(data: TrainingData, options: dict, rng: np.random.Generator,
                    progress: Callable | None = None, checkpoint: Path | None = None) -> LinearARModel:
    from .training import fit_linear_ar  # least squares: no random numbers, no epochs to report or checkpoint

    return fit_linear_ar(data, options["ridge"])


@register_prior("linear-ar", summary="linear autoregressive model of the pose (an example plugin's prior)",
                model_files="one", train=train_linear_ar, train_options=TRAIN_OPTIONS,
                options=part_options(LinearARPrior.PARTS))
def build_linear_ar(context: PriorContext, model_files: Sequence[Path | LinearARModel],
                    options: dict) -> LinearARPrior:
    from .file import load_linear_ar
    from .model import LinearARModel

    model = loaded(model_files[0], load_linear_ar, LinearARModel, "linear autoregressive", device=context.device)
    model.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps,
                           source_of(model_files[0]))
    return LinearARPrior(model, device=context.device, options=options)
