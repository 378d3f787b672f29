"""The CRBM motion prior (Taylor 2009, Sec. 6.3-6.4): a CRBM drawing each particle's next frame, plus parts.

The model is :mod:`priors.crbm.model` (trained by :mod:`priors.crbm.training`, read by :mod:`priors.crbm.file`);
the pose step and the parts are :class:`priors.conditional.ConditionalPrior`'s. Registered as the ``crbm``
prior (``train`` and ``track --prior crbm``); several model files all of one order form an ensemble
(:class:`priors.ensemble.EnsemblePrior`).
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from priors.common import gibbs_steps_option, loaded, source_of
from priors.conditional import ConditionalPrior
from priors.ensemble import EnsemblePrior
from priors.learned import PartSpec, SmallModel, part_options
from priors.parts import GroundDiffusion, GrowingModels, HeightOffset, PaceInput, Part, PostureOffset
from priors.settings import CRBM_TRAIN_OPTIONS
from tracker.core.errors import InputError
from tracker.engine.prior import PriorState
from tracker.engine.registry import PriorContext, TrainingData, register_prior

if TYPE_CHECKING:  # the model and torch load when the prior is built or trained, not when it registers
    import torch

    from priors.crbm.model import CRBMModel

#: Default Gibbs steps per sample of the CRBM prior. Chosen on the tuning folds of the leave-one-subject-out
#: protocol (folds 2 and 7, CRBM-3, 1000 particles, 5 seeds; docs/methods_report.md): 30, 10 and 5 steps gave the same
#: error with 4 views and within the seeds' spread with one, and 5 steps sample about 5x faster than 30.
GIBBS_STEPS = 5
#: Default height spread (mm) of a CRBM trained with a pace input (one trained on the walks of several people):
#: each particle's own root-height offset at the start. It won against none on the leave-one-subject-out
#: protocol's tuning and test folds (docs/methods_report.md); 50 mm is the spread of the shared subjects' root
#: heights. Without a pace input the default is 0.
PACED_HEIGHT_SPREAD = 50.0
#: Default posture gain of a CRBM trained with a pace input: it won against none and against 0.2 and 0.4 on the
#: tuning and test folds (docs/methods_report.md). Without a pace input the default is 0.
PACED_POSTURE_GAIN = 0.1
#: The parts of a CRBM prior (and of the neural prior), in the order a step runs them: the
#: :class:`~priors.conditional.ConditionalPrior`'s, a model trained with a pace input taking a height offset of
#: :data:`PACED_HEIGHT_SPREAD` and a posture gain of :data:`PACED_POSTURE_GAIN` by default, one without neither.
PACED_PARTS = (PartSpec("pace", PaceInput, paced=True),
               PartSpec("height", HeightOffset, paced_defaults={"height_spread": PACED_HEIGHT_SPREAD}),
               PartSpec("posture", PostureOffset, paced_defaults={"posture_gain": PACED_POSTURE_GAIN}),
               PartSpec("ground", GroundDiffusion))


class CRBMPrior(ConditionalPrior):
    """Samples every particle's next pose from its own history with a CRBM (one batch, torch).

    ``models`` of increasing order grow the history (each file carries the lower orders it was trained with).
    ``mode`` is ``'gibbs'`` (``gibbs_steps`` alternating Gibbs steps, for tracking) or ``'free-energy'`` (the
    best guess, eq. 4.19, for prediction). The parts are :data:`PACED_PARTS` (``ground``, ``pace``, ``height``,
    ``posture``, given as keywords or by ``options``: :class:`~priors.conditional.ConditionalPrior`); a part left
    unset takes its default for these models: a model trained with a pace input gets a
    :class:`~priors.parts.PaceInput`, a height offset of :data:`PACED_HEIGHT_SPREAD` and a posture gain of
    :data:`PACED_POSTURE_GAIN`; one without gets neither offset. Pass ``HeightOffset(0)`` or ``PostureOffset(0)``
    to turn one off.
    """

    name = "crbm"
    PARTS: ClassVar[tuple[PartSpec, ...]] = PACED_PARTS
    SMALL_MODELS: ClassVar[tuple[SmallModel, ...]] = (
        SmallModel({"order": 3, "hidden": 20, "epochs": 3}),
        SmallModel({"order": 2, "hidden": 20, "epochs": 3, "pace_input": True}, clips=3, label="paced"))

    def __init__(self, models: Sequence[CRBMModel], gibbs_steps: int = GIBBS_STEPS, *, device: str = "cpu",
                 mode: str = "gibbs", options: Mapping[str, Any] | None = None, **parts: Part | None):
        from priors.crbm.model import CRBM

        grown = GrowingModels(models, "CRBM")
        if isinstance(gibbs_steps, bool) or not isinstance(gibbs_steps, (int, np.integer)) or gibbs_steps < 1:
            raise InputError(f"Gibbs steps must be an integer of at least 1, got {gibbs_steps!r}")
        if mode not in ("gibbs", "free-energy"):
            raise InputError(f"CRBM prior mode must be 'gibbs' or 'free-energy', got {mode!r}")
        super().__init__(grown, device=device, options=options, **parts)
        self.gibbs_steps, self.mode = int(gibbs_steps), mode
        for m in grown:
            m.crbm.W, m.crbm.A, m.crbm.B, m.crbm.a, m.crbm.b = (
                getattr(m.crbm, k).to(self.device) for k in CRBM.PARAMS)

    def draw(self, model: CRBMModel, conditioning: torch.Tensor, generator: torch.Generator,
             state: PriorState) -> torch.Tensor:
        import torch

        if self.mode == "free-energy":  # the deterministic best guess (eq. 4.19)
            return model.crbm.best_guess(conditioning)
        with torch.no_grad():
            return model.crbm.gibbs(conditioning, self.gibbs_steps, generator)

    def settings(self) -> dict:
        return {**super().settings(), "gibbs_steps": self.gibbs_steps, "mode": self.mode}


def train_crbm_from_data(data: TrainingData, options: dict, rng: np.random.Generator,
                         progress: Callable[[int, int, dict], None] | None = None, checkpoint: Path | None = None,
                         resume: bool = False) -> CRBMModel:
    """``train --prior crbm``: :func:`priors.crbm.training.train_crbm_prior` (imported, with torch, when called)."""
    from priors.crbm.training import train_crbm_prior

    return train_crbm_prior(data, options, rng, progress, checkpoint, resume)


@register_prior(
    "crbm", summary="Conditional RBM (Taylor 2009); several model files of increasing order grow the history, "
                    "several of one order form an ensemble",
    model_files="several", train=train_crbm_from_data, train_options=CRBM_TRAIN_OPTIONS, resumable=True,
    options=(gibbs_steps_option(GIBBS_STEPS), *part_options(CRBMPrior.PARTS)))
def build_crbm(context: PriorContext, model_files: Sequence[Path], options: dict) -> CRBMPrior | EnsemblePrior:
    """The CRBM prior of ``model_files``: models of increasing order grow the history; several files all of one
    order (each with the growth models it carries) form an ensemble, each drawing its share of the particles."""
    from priors.crbm.file import load_crbm
    from priors.crbm.model import CRBMModel

    models = [loaded(m, load_crbm, CRBMModel, "CRBM", device=context.device) for m in model_files]
    for given, m in zip(model_files, models):
        m.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps, source_of(given))

    def prior(of: list[CRBMModel]) -> CRBMPrior:
        return CRBMPrior(of, options["gibbs_steps"], device=context.device, options=options)

    if len(models) > 1 and len({m.order for m in models}) == 1:
        return EnsemblePrior([prior([m]) for m in models])
    return prior(models)
