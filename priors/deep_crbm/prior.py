"""The deep CRBM motion prior (``deep-crbm``): the two layers of :mod:`priors.deep_crbm.model` draw each
particle's next frame once ``N + M`` history frames are real poses; the pose step and the parts are the CRBM
prior's (:class:`priors.crbm.prior.CRBMPrior`): with fewer real history frames the first layer alone (and the lower
orders its file carries) draws the pose, so the history grows through the lower orders first (Taylor 2009,
Sec. 6.4).
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from priors.common import gibbs_steps_option, loaded, source_of
from priors.crbm.prior import CRBMPrior
from priors.learned import PartSpec, SmallModel, part_options
from priors.parts import GroundDiffusion, HeightOffset, Part, PostureOffset
from priors.settings import CRBM_TRAIN_OPTIONS, TopConfig
from tracker.engine.prior import PriorState
from tracker.engine.registry import Option, PriorContext, TrainingData, register_prior

if TYPE_CHECKING:  # torch and the models load when the prior is built or trained, not when it registers
    import torch

    from priors.deep_crbm.model import DeepCRBMModel


class DeepCRBMPrior(CRBMPrior):
    """Samples every particle's next pose through both layers once ``N + M`` history frames are real poses, and
    with the first layer (or the lower orders its file carries) before; the pose step, the parts and the
    per-particle state are the CRBM prior's. Its first layer takes no pace input (its file refuses one), so its
    parts are the height and posture offsets (off by default) and the ground diffusion."""

    name = "deep-crbm"
    PARTS: ClassVar[tuple[PartSpec, ...]] = (PartSpec("height", HeightOffset), PartSpec("posture", PostureOffset),
                                             PartSpec("ground", GroundDiffusion))
    SMALL_MODELS: ClassVar[tuple[SmallModel, ...]] = (
        SmallModel({"order": 2, "hidden": 20, "epochs": 3, "top_order": 1, "top_hidden": 10, "top_epochs": 3}),)

    def __init__(self, model: DeepCRBMModel, gibbs_steps: int = 30, *, device: str = "cpu",
                 options: Mapping[str, Any] | None = None, **parts: Part | None):
        from priors.crbm.model import CRBM

        super().__init__([model.bottom], gibbs_steps, device=device, options=options, **parts)
        self.deep = model
        for k in CRBM.PARAMS:
            setattr(model.top, k, getattr(model.top, k).to(self.device))
        self.order = model.order

    def settings(self) -> dict:
        return {**super().settings(), "layers": [self.deep.bottom.order, self.deep.top.order],
                "hidden": [self.deep.bottom.crbm.n_hidden, self.deep.top.n_hidden]}

    def model_for(self, available: int):
        """Both layers once ``N + M`` history frames are real poses, the first layer's models before."""
        return self.deep if available >= self.deep.order else super().model_for(available)

    def draw(self, model, conditioning: torch.Tensor, generator: torch.Generator,
             state: PriorState) -> torch.Tensor:
        if model is not self.deep:
            return super().draw(model, conditioning, generator, state)
        import torch

        from priors.deep_crbm.model import deep_gibbs

        with torch.no_grad():
            return deep_gibbs(self.deep.bottom.crbm, self.deep.top, conditioning, self.gibbs_steps, generator)

    def label_for(self, available: int) -> str:
        if available >= self.deep.order:
            return f"deep crbm order {self.deep.bottom.order}+{self.deep.top.order}"
        return f"crbm order {self.model_for(available).order}"


def train_deep_crbm_from_data(data: TrainingData, options: dict, rng: np.random.Generator,
                              progress: Callable[[int, int, dict], None] | None = None,
                              checkpoint: Path | None = None, resume: bool = False) -> DeepCRBMModel:
    """``train --prior deep-crbm``: :func:`priors.deep_crbm.training.train_deep_crbm_prior` (imported, with torch,
    when called)."""
    from priors.deep_crbm.training import train_deep_crbm_prior

    return train_deep_crbm_prior(data, options, rng, progress, checkpoint, resume)


DEEP_TRAIN_OPTIONS = tuple(o for o in CRBM_TRAIN_OPTIONS if o.name != "pace_input") + (
    Option("top_order", int, TopConfig.order, "order M of the second layer", minimum=1, maximum=100),
    Option("top_hidden", int, TopConfig.hidden, "hidden units of the second layer", minimum=1,
           maximum=100000),
    Option("top_epochs", int, TopConfig.epochs, "epochs of the second layer", minimum=1,
           maximum=1000000),
)


@register_prior(
    "deep-crbm", summary="two-layer CRBM (Taylor 2009, Sec. 4.3): a second CRBM on the first one's hidden units",
    model_files="one", train=train_deep_crbm_from_data, train_options=DEEP_TRAIN_OPTIONS, resumable=True,
    options=(gibbs_steps_option(30), *part_options(DeepCRBMPrior.PARTS)))
def build_deep_crbm(context: PriorContext, model_files: Sequence[Path], options: dict) -> DeepCRBMPrior:
    from priors.deep_crbm.file import load_deep_crbm
    from priors.deep_crbm.model import DeepCRBMModel

    model = loaded(model_files[0], load_deep_crbm, DeepCRBMModel, "deep CRBM", device=context.device)
    model.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps,
                           source_of(model_files[0]))
    return DeepCRBMPrior(model, options["gibbs_steps"], device=context.device, options=options)
