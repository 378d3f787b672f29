"""The training settings of the learned priors, and the options that set them, without the models.

The command line lists every prior's options (``train --help``, ``track --help``) from these; they import no
torch, so the models (:mod:`priors.crbm.model`, :mod:`priors.fcrbm.model`, :mod:`priors.gpdm.model`, which
re-export them) load only when a prior is built or trained.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from numbers import Integral
from typing import ClassVar

from tracker.core.errors import InputError
from tracker.engine.registry import Option


#: Most mini-batch updates of one contrastive-divergence training stage (one order of a model, or a deep model's
#: second layer) by default: where the data has more windows than that allows, the epochs are cut to
#: ``ceil(updates / mini-batches per epoch)`` (:meth:`ContrastiveConfig.epochs_for`), so that training time stops
#: growing with the data. 50,000 updates leave every training set of up to 10,000 windows (at 100 windows per
#: mini-batch and 500 epochs) as it was: the shipped experiments train a CRBM on at most about 4,000 windows (at
#: 60 Hz), and CMU's shared walks, runs, punches and kicks without one subject about 9,400. On two CPU cores a
#: CRBM stage then takes at most about a minute and a half (docs/guide/training.md, "Large corpora", has the
#: measurements).
UPDATE_BUDGET = 50_000
#: The FCRBM's budget: an update costs about two and a half CRBM updates; 25,000 leave its shipped training sets
#: (at most about 8,300 label-balanced windows at 300 epochs) as they were.
FCRBM_UPDATE_BUDGET = 25_000


@dataclass
class ContrastiveConfig:
    """The training settings of every conditional RBM trained here by contrastive divergence (learning rates per
    mini-batch of averaged statistics). A model's config subclasses it, changing defaults and adding its own."""

    order: int = 3
    hidden: int = 150
    epochs: int = 500
    cd_k: int = 10
    batch_size: int = 100
    learning_rate: float = 1e-3
    autoregressive_learning_rate: float = 1e-5
    momentum: float = 0.9
    weight_decay: float = 2e-4
    #: Most mini-batch updates of the training (:meth:`epochs_for`): the epochs adapt to the data's size.
    updates: int = UPDATE_BUDGET

    #: What messages call the model.
    KIND: ClassVar[str] = "CRBM"
    #: The settings that count something and must be whole numbers of at least 1.
    COUNTS: ClassVar[tuple[str, ...]] = ("order", "hidden", "epochs", "cd_k", "batch_size", "updates")

    def epochs_for(self, windows: int) -> int:
        """The epochs a training on ``windows`` training windows runs: ``epochs``, or fewer where they would take
        more than ``updates`` mini-batch updates, ``ceil(updates / ceil(windows / batch_size))``."""
        batches = max(math.ceil(windows / self.batch_size), 1)
        return min(self.epochs, math.ceil(self.updates / batches))

    def check(self):
        """The config itself, checked: counts whole and at least 1, rates and weight decay in [0, 1), momentum in
        [0, 1), and a ``history_noise`` (where the model has one) 'auto' or a non-negative number. A bad setting is
        an :class:`InputError` naming it."""
        for name in self.COUNTS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, Integral) or value < 1:
                raise InputError(f"{self.KIND} {name} must be an integer of at least 1, got {value!r}")
        for name in ("learning_rate", "autoregressive_learning_rate", "weight_decay", "momentum"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < 1:
                raise InputError(f"{self.KIND} {name} must lie in [0, 1), got {value!r}")
        noise = getattr(self, "history_noise", "auto")
        if noise != "auto" and (isinstance(noise, bool) or not isinstance(noise, (int, float)) or not noise >= 0):
            raise InputError(f"history noise must be 'auto' or a non-negative number, got {noise!r}")
        return self


@dataclass
class CRBMConfig(ContrastiveConfig):
    """Training settings of a CRBM: :class:`ContrastiveConfig`'s, and the CRBM's own."""

    history_noise: float | str = "auto"
    sparsity_target: float | None = None
    sparsity_cost: float = 0.1
    #: Condition on each frame's pace (:func:`~tracker.core.representation.clip_log_pace`, one extra input before
    #: the history), so that one model walks at every pace it was shown, at the pace the tracker gives it.
    pace_input: bool = False
    #: Fraction of each clip (its last frames) held out to choose the epoch: every ``validation_every`` epochs the
    #: one-step prediction error (free-energy best guess, normalised units) on the held-out windows is measured and
    #: the weights of the best check are kept (Taylor 2009 held out 10%). 0: no validation, the last epoch's weights.
    validation: float = 0.0
    validation_every: int = 10

    def check(self) -> "CRBMConfig":
        super().check()
        for name, value in (("sparsity", self.sparsity_target), ("validation", self.validation)):
            crbm_train_option(name).parse(value, self.KIND)  # the bounds the options declare
        if int(self.validation_every) < 1:
            raise InputError(f"validation_every must be at least 1, got {self.validation_every}")
        return self


@dataclass
class TopConfig(ContrastiveConfig):
    """Settings of the second layer: :class:`~priors.settings.ContrastiveConfig`'s, with a smaller second layer."""

    order: int = 2
    hidden: int = 100
    epochs: int = 200

    KIND: ClassVar[str] = "deep CRBM top"


#: Temperature of the labels' evidence in mixture inference (the likelihood to the power ``1 / T`` when the
#: labels are weighed against each other). Chosen on a tuning fold (``docs/methods_report.md``).
STYLE_TEMPERATURE = 10.0


@dataclass
class FCRBMConfig(ContrastiveConfig):
    """Training settings of an FCRBM (Taylor & Hinton 2009, Sec. 4.2): :class:`ContrastiveConfig`'s
    with the paper's defaults, and the factors, style features, history noise and label balance."""

    epochs: int = 300
    updates: int = FCRBM_UPDATE_BUDGET
    learning_rate: float = 1e-2
    autoregressive_learning_rate: float = 1e-3
    factors: int = 100
    features: int = 20
    history_noise: float | str = "auto"
    balance: bool = True

    KIND: ClassVar[str] = "FCRBM"
    COUNTS: ClassVar[tuple[str, ...]] = ContrastiveConfig.COUNTS + ("factors", "features")


DYNAMICS = ("linear", "rbf", "linear+rbf")
#: Sparse approximations (:class:`priors.gpdm.model._Sparse`): ``dtc`` (the default; deterministic training conditional, or
#: projected process, Seeger et al. 2003), ``vfe`` (DTC plus Titsias' 2009 trace term: a lower bound on the
#: evidence), ``fitc`` (Snelson & Ghahramani 2006). docs/reference/priors.md compares them: DTC forecast best overall, VFE
#: worst, and FITC learned a near-zero dynamics noise.
SPARSE_METHODS = ("dtc", "vfe", "fitc")

#: Largest training set (frames) on which ``inducing=None`` (auto) keeps the exact model; above it the GPs are
#: sparse with :data:`AUTO_INDUCING` inducing frames. An exact objective evaluation costs O(N^3) (600 frames: 0.09 s
#: on one core; 1786 frames took 3 s per L-BFGS iteration), a sparse one O(N m^2) (2000 frames, m = 200: 0.1 s);
#: the exact prior's step costs O(P N^2) for P particles (1000 particles, 500 frames: about 16 ms; 600: 23 ms).
EXACT_MAX_FRAMES = 500
#: Inducing frames of the auto setting (docs/reference/performance.md has the measurements behind it).
AUTO_INDUCING = 200
#: Most training frames of a GPDM by default: a larger corpus is cut to stretches of its clips
#: (:mod:`priors.gpdm.subset`), so that the training's cost stops growing with the corpus (sparse, with
#: :data:`AUTO_INDUCING` inducing frames); the shipped experiments train GPDMs on at most about 1,800.
GPDM_MAX_FRAMES = 3000
#: Fewest inducing frames a sparse model may have.
MIN_INDUCING = 10
#: Largest latent noise (multiples of the predictive standard deviation) of the tracking prior: far beyond any
#: useful setting, and larger values throw particles kilometres away.
MAX_LATENT_NOISE = 100.0


@dataclass
class GPDMConfig:
    latent_dim: int = 3
    dynamics: str = "linear+rbf"
    order: int = 1
    balance: float = 1.0
    iterations: int = 300
    w_update_every: int = 10
    #: ``None``: exact up to :data:`EXACT_MAX_FRAMES` frames, else :data:`AUTO_INDUCING` inducing frames;
    #: ``0``: always exact; ``m > 0``: sparse with ``min(m, N)`` inducing frames (see :func:`inducing_frames`).
    inducing: int | None = None
    sparse_method: str = "dtc"

    def check(self) -> "GPDMConfig":
        if self.latent_dim < 1:
            raise InputError(f"latent dimension must be at least 1, got {self.latent_dim}")
        if self.dynamics not in DYNAMICS:
            raise InputError(f"dynamics kernel must be one of {', '.join(DYNAMICS)}, got {self.dynamics!r}")
        if self.order not in (1, 2):
            raise InputError(f"GPDM order must be 1 or 2, got {self.order}")
        if not self.balance > 0:
            raise InputError(f"the balance M must be positive, got {self.balance}")
        if self.iterations < 1 or self.w_update_every < 1:
            raise InputError("iterations and the W update interval must be at least 1")
        if self.inducing is not None and self.inducing != 0 and self.inducing < MIN_INDUCING:
            raise InputError(f"inducing frames must be 0 (exact) or at least {MIN_INDUCING}, got {self.inducing}")
        if self.sparse_method not in SPARSE_METHODS:
            raise InputError(f"sparse method must be one of {', '.join(SPARSE_METHODS)}, got {self.sparse_method!r}")
        return self

    def inducing_count(self, n_frames: int) -> int:
        """Inducing frames for a training set of ``n_frames`` frames (0: the exact model)."""
        if self.inducing is None:
            return 0 if n_frames <= EXACT_MAX_FRAMES else AUTO_INDUCING
        return min(self.inducing, n_frames)


#: Least spread (std of the training frames' log pace) for which ``train`` gives a CRBM a pace input by default:
#: a 10% spread of paces. One person's walks vary by less (subject 7's four walks: 0.07; one walk: 0.01), and a
#: model trained on them could not learn what the input means; the walks of three or more of the shared subjects
#: vary by 0.14-0.58 (set a priori from these spreads, not from tracking results).
PACE_SPREAD_FOR_INPUT = 0.1

CRBM_TRAIN_OPTIONS = (
    Option("order", int, CRBMConfig.order, "CRBM order N", minimum=1, maximum=100),
    Option("hidden", int, CRBMConfig.hidden, "hidden units", minimum=1, maximum=100000),
    Option("epochs", int, CRBMConfig.epochs, "passes through the data (fewer where they exceed --updates)",
           minimum=1, maximum=1000000),
    Option("updates", int, CRBMConfig.updates, "most mini-batch updates: on a large corpus the epochs are cut to "
           "ceil(updates / mini-batches per epoch), so that training time stops growing with the data",
           minimum=1, maximum=10 ** 9),
    Option("cd_k", int, CRBMConfig.cd_k, "Gibbs steps of contrastive divergence", minimum=1,
           maximum=10000),
    Option("batch_size", int, CRBMConfig.batch_size, "windows per mini-batch", minimum=1,
           maximum=1000000),
    Option("history_noise", str, "auto",
           "std of the noise added to the history in training (normalised units), or 'auto': per feature, the 99th "
           "percentile of its frame-to-frame change"),
    Option("sparsity", float, None, "target mean activation of the hidden units", minimum=0.0, strict=True,
           maximum=1.0, strict_max=True, default_note="none: no sparsity term"),
    Option("checkpoint_every", int, None, "also save the training state every this many epochs, for train --resume",
           minimum=1, default_note="never"),
    Option("grow_from", str, "1", "lower orders trained alongside and saved in the same file, which grow the "
                                  "history from the known frames (Taylor 2009, Sec. 6.4); 'none' to skip"),
    Option("pace_input", bool, None, "condition the model on each frame's pace (log ground speed averaged over one "
                                     "second), which each particle carries while tracking",
           default_note=f"on when the clips' paces vary, std of log pace >= {PACE_SPREAD_FOR_INPUT:g}, e.g. the walks "
                        "of several people; --no-pace-input to turn it off"),
    Option("validation", float, CRBMConfig.validation,
           "fraction of each clip (its last frames) held out to choose the epoch: the weights of the epoch with the "
           "least held-out one-step error, checked every 10 epochs, are kept",
           minimum=0.0, maximum=0.5, default_note="0: the last epoch's"),
)


def crbm_train_option(name: str) -> Option:
    """The CRBM training option ``name`` of :data:`CRBM_TRAIN_OPTIONS`."""
    return next(o for o in CRBM_TRAIN_OPTIONS if o.name == name)
