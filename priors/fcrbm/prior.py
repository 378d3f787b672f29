"""The FCRBM motion prior: every particle carries a style label, and its pose is drawn by the FCRBM with the label
clamped (Taylor 2009, Ch. 5; the model is :mod:`priors.fcrbm.model`). Registered as ``fcrbm``.

An equal share of the particles carries each label and the filter weighs the labels against each other
(mixture tracking, :mod:`tracker.engine.multiple_models`, switching with probability ``style_switch`` per frame). The filter's
posterior over the style is the weighted histogram of the particles' labels (:meth:`FCRBMPrior.summarize`),
recorded per frame in ``result.json``.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from priors.common import gibbs_steps_option, loaded, source_of
from priors.conditional import ConditionalPrior
from priors.learned import PartSpec, SmallModel, part_options
from priors.parts import GroundDiffusion, GrowingModels, HeightOffset, Part, PostureOffset
from priors.settings import CRBM_TRAIN_OPTIONS, STYLE_TEMPERATURE, FCRBMConfig
from tracker.core.errors import InputError
from tracker.engine.multiple_models import Mixing, switching
from tracker.engine.prior import PriorState
from tracker.engine.registry import Option, PriorContext, TrainingData, register_prior

if TYPE_CHECKING:  # the model and torch load when the prior is built or trained, not when it registers
    import torch

    from priors.fcrbm.model import FCRBMModel


def transition_styles(n_labels: int, first: int, second: int, frames: int, start: int, length: int) -> np.ndarray:
    """Label rows ``frames x n_labels``: label ``first`` until frame ``start``, then a linear blend over ``length``
    frames into label ``second`` (the paper blends over 200 frames at 60 Hz; a frame-to-frame change is jerky)."""
    w = np.clip((np.arange(frames) - start + 1) / max(length, 1), 0.0, 1.0)
    out = np.zeros((frames, n_labels))
    out[:, first] += 1 - w
    out[:, second] += w
    return out


def generate(model: FCRBMModel, start: np.ndarray, styles: np.ndarray, rng: np.random.Generator,
             gibbs_steps: int = 30) -> np.ndarray:
    """Poses ``T x D`` generated after the known poses ``start`` ``n0 x D`` (``n0 >= model.order``) with the
    label rows ``styles`` ``T x P`` clamped frame by frame (one-hot for a fixed style, blends for mixtures and
    transitions); no ground-plane diffusion."""
    styles = np.asarray(styles, float)
    if styles.ndim != 2 or styles.shape[1] != len(model.labels):
        raise InputError(f"styles must be T x {len(model.labels)} (one column per label), got {styles.shape}")
    prior = FCRBMPrior([model], gibbs_steps, ground=GroundDiffusion(0.0))
    start = np.atleast_2d(np.asarray(start, float))
    n = prior.order
    if len(start) < n:
        raise InputError(f"generation needs {n} known frames, got {len(start)}")
    state = prior.start(start, 1, rng)
    history, out = start[None, -n:], []
    for row in styles:
        x, state = prior.sample_styled(history, n, state, row[None], rng)
        history = np.concatenate([history[:, 1:], x[:, None]], axis=1)
        out.append(x[0])
    return np.array(out)


# ---------------------------------------------------------------------------
# As a tracking prior
# ---------------------------------------------------------------------------


def parse_style_schedule(text: str, labels: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """The ``style`` option: one label (``run``) for every frame, or a schedule ``walk,run@120`` (a label from
    frame 0, then each ``label@frame`` from that sequence frame on) for an oracle that knows when the person
    changes activity. Returns the first frames ``(K,)`` (increasing, starting at 0) and label indices ``(K,)``."""
    frames, indices = [], []
    for i, part in enumerate(str(text).split(",")):
        label, at, frame = part.strip().partition("@")
        if label not in labels:
            raise InputError(f"style {label!r} is not a label of this FCRBM (its labels: {', '.join(labels)})")
        if i == 0 and at:
            raise InputError(f"style schedule {text!r}: the first label holds from frame 0 (write 'walk,run@120')")
        if i > 0:
            if not at or not frame.strip().isdigit():
                raise InputError(f"style schedule {text!r}: after the first label each entry is label@frame "
                                 "(e.g. run@120)")
            if int(frame) <= frames[-1]:
                raise InputError(f"style schedule {text!r}: the frames must increase")
        frames.append(int(frame) if at else 0)
        indices.append(labels.index(label))
    return np.array(frames, np.int64), np.array(indices, np.int64)




class FCRBMPrior(ConditionalPrior):
    """Samples every particle's next pose with an FCRBM, the particle's own style label clamped.

    Per-particle state: :class:`~priors.conditional.ConditionalPrior`'s (the pending root step) with ``style``
    ``(P,)``, the label indices, and ``clock`` ``(P,)``, the sequence frame the next sample is for (which a style
    schedule reads). An unknown style is inferred by mixture tracking: every label keeps an equal share of the
    particles, and the filter moves weight between the labels by their tempered evidence and switches with
    probability ``style_switch`` per frame (:meth:`mixing`). ``style`` fixes every particle's label (no switching: the
    oracle), or follows a schedule. :meth:`summarize` gives the filter's posterior over the labels. The parts
    (an FCRBM takes no pace input): the height and posture offsets (off by default) and the ground diffusion.
    """

    name = "fcrbm"
    summary_kind = "posterior"
    PARTS: ClassVar[tuple[PartSpec, ...]] = (PartSpec("height", HeightOffset), PartSpec("posture", PostureOffset),
                                             PartSpec("ground", GroundDiffusion))
    SMALL_MODELS: ClassVar[tuple[SmallModel, ...]] = (
        SmallModel({"labels": "a,b", "order": 2, "hidden": 20, "factors": 10, "features": 4, "epochs": 3},
                   clips=2),)

    def __init__(self, models: Sequence[FCRBMModel], gibbs_steps: int = 30, *, device: str = "cpu",
                 style_switch: float = 0.05, style: str | None = None, style_temperature: float = STYLE_TEMPERATURE,
                 options: Mapping[str, Any] | None = None, **parts: Part | None):
        grown = GrowingModels(models, "FCRBM")
        first = grown.first
        checks = {"Gibbs steps": (gibbs_steps, gibbs_steps >= 1),
                  "style switch": (style_switch, 0 <= style_switch <= 1),
                  "style temperature": (style_temperature, style_temperature >= 1)}
        for what, (value, ok) in checks.items():
            if not ok:
                raise InputError(f"FCRBM prior: bad {what} {value!r}")
        super().__init__(grown, device=device, options=options, **parts)
        self.labels = list(first.labels)
        self.style = None if style in (None, "") else str(style)
        self.schedule = None if self.style is None else parse_style_schedule(self.style, self.labels)
        self.style_switch = float(style_switch)
        self.style_temperature = float(style_temperature)
        self.gibbs_steps = int(gibbs_steps)
        for m in grown:
            m.fcrbm.to(self.device)
        self.summary_names = tuple(self.labels)

    def settings(self) -> dict:
        return {**super().settings(), "gibbs_steps": self.gibbs_steps, "labels": self.labels, "style": self.style,
                "style_switch": self.style_switch,
                "style_temperature": self.style_temperature}

    def draw(self, model: FCRBMModel, conditioning: torch.Tensor, generator: torch.Generator,
             state: PriorState) -> torch.Tensor:
        """The FCRBM's Gibbs samples with the label rows ``state["style_rows"]`` ``P x L`` clamped."""
        import torch

        rows = torch.as_tensor(np.asarray(state["style_rows"]), dtype=torch.float32, device=self.device)
        with torch.no_grad():
            return model.fcrbm.gibbs(conditioning, rows, self.gibbs_steps, generator)

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        """The pending step of the last known frame, and every particle's label: the ``style`` (schedule) given;
        else an equal share of the particles per label (particle ``i`` label ``i mod L``). The clock starts at the first tracked frame, ``len(known)``."""
        state = super().start(known, n_particles, rng)
        clock = np.full(n_particles, len(known), np.int64)
        if self.schedule is not None:
            style = self.scheduled(clock)
        else:
            style = np.arange(n_particles) % len(self.labels)
        return {**state, "style": style.astype(np.int64), "clock": clock}

    def restart(self, state: PriorState, recent: np.ndarray, n_particles: int,
                rng: np.random.Generator) -> PriorState:
        """:meth:`start` from ``recent``, the clock carried on past the lost frame."""
        new = super().restart(state, recent, n_particles, rng)
        clock = np.full(n_particles, int(np.asarray(state["clock"])[0]) + 1, np.int64)
        style = self.scheduled(clock) if self.schedule is not None else new["style"]
        return {**new, "clock": clock, "style": style}

    def scheduled(self, clock: np.ndarray) -> np.ndarray:
        """The labels ``(P,)`` the ``style`` schedule gives at frames ``clock`` ``(P,)``."""
        frames, indices = self.schedule
        return indices[np.searchsorted(frames, clock, side="right") - 1]

    def mixing(self) -> Mixing | None:
        """For an unknown style, the labels are components the filter keeps apart
        (:class:`~tracker.engine.multiple_models.ComponentPrior`): one per label (the particles carrying it), switching with
        probability ``style_switch``, the evidence tempered by ``style_temperature``; None for a known style."""
        if self.schedule is not None or len(self.labels) < 2:
            return None
        return Mixing(tuple(self.labels), switching(len(self.labels), self.style_switch), self.style_temperature)

    def component_of(self, state: PriorState) -> np.ndarray:
        """Each particle's label ``(P,)``."""
        return np.asarray(state["style"])

    def relabel(self, state: PriorState, component: np.ndarray) -> PriorState:
        return {**state, "style": np.array(component, np.int64)}

    def sample_styled(self, history: np.ndarray, available: int, state: PriorState, rows: np.ndarray,
                      rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        """Next poses ``P x D`` and the pose step's next state with the label rows ``rows`` ``P x L`` (one-hot, or
        blends) clamped."""
        return super().sample(history, available, {**state, "style_rows": rows}, rng)

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        clock = np.asarray(state["clock"])
        style = self.scheduled(clock) if self.schedule is not None else np.asarray(state["style"])
        onehot = np.eye(len(self.labels), dtype=np.float32)[style]
        poses, new = self.sample_styled(history, available, state, onehot, rng)
        return poses, {**new, "style": style, "clock": clock + 1}

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray:
        """The posterior over the labels ``(L,)``: the normalised ``weights`` ``(P,)`` summed per label."""
        return np.bincount(np.asarray(state["style"]), weights=weights, minlength=len(self.labels))


def train_fcrbm_prior(data: TrainingData, options: dict, rng: np.random.Generator,
                      progress: Callable[[int, int, dict], None] | None = None,
                      checkpoint: Path | None = None, resume: bool = False) -> FCRBMModel:
    """``train --prior fcrbm``: an FCRBM of ``options['order']`` (and the lower orders it grows from) on the clips
    of ``data``, labelled by ``options['labels']`` (one per clip, in clip order). With ``checkpoint`` (a file) the
    training state is saved there every ``checkpoint_every`` epochs and when the training is interrupted;
    ``resume`` continues from it to the model an uninterrupted run gives."""
    from copy import copy

    from priors.common import read_model_file, torch_save_atomic
    from priors.crbm.training import growth_orders, parse_history_noise
    from priors.fcrbm.file import model_from_document
    from priors.fcrbm.model import CHECKPOINT_FORMAT, parse_labels
    from priors.fcrbm.training import train_fcrbm, training_windows

    if options["labels"] is None:
        raise InputError("the FCRBM needs one label per training clip: --labels walk,walk,run (labels = "
                         "\"walk,walk,run\" in an experiment's train options)")
    clip_labels = parse_labels(options["labels"], data.sources or [f"clip {i + 1}" for i in range(len(data.clips))])
    noise = parse_history_noise(options["history_noise"])
    config = FCRBMConfig(order=options["order"], hidden=options["hidden"], factors=options["factors"],
                         features=options["features"], epochs=options["epochs"], cd_k=options["cd_k"],
                         batch_size=options["batch_size"], updates=options["updates"],
                         learning_rate=options["learning_rate"],
                         autoregressive_learning_rate=options["autoregressive_learning_rate"],
                         history_noise=noise).check()
    orders = growth_orders(options["grow_from"], config.order) + [config.order]
    labels = list(dict.fromkeys(clip_labels))
    lengths = [len(c) for c in data.clips]
    epochs = [config.epochs_for(training_windows(lengths, clip_labels, o, config.balance)) for o in orders]
    total = sum(epochs)
    models: list[FCRBMModel] = []
    state = None
    if resume:  # the growth models finished before, and the training state of the one in progress
        if checkpoint is None or not checkpoint.exists():
            raise InputError("no training checkpoint to resume from", checkpoint)
        doc = read_model_file(checkpoint, CHECKPOINT_FORMAT, "FCRBM training checkpoint")
        if "training_state" not in doc or doc.get("stage_orders") != orders or doc.get("labels") != labels:
            raise InputError("the checkpoint is not of this training (other orders or labels, or a finished "
                             "model)", checkpoint)
        models = [model_from_document(g, checkpoint) for g in doc["growth"]]
        state = doc["training_state"]
        for _ in models:  # the draws the finished stages took from rng
            rng.integers(2 ** 62)

    def save(stage_model: FCRBMModel, training_state: dict) -> None:
        snapshot = copy(stage_model)
        snapshot.growth = list(models)
        torch_save_atomic({**snapshot.to_document(), "format": CHECKPOINT_FORMAT, "training_state": training_state,
                           "stage_orders": orders}, checkpoint)  # a model is never half-written

    every, first = options.get("checkpoint_every") or 0, len(models)
    for i in range(first, len(orders)):
        report = None if progress is None else (
            lambda epoch, err, before=sum(epochs[:i]): progress(before + epoch, total, {"reconstruction": err}))
        models.append(train_fcrbm(list(data.clips), clip_labels, replace(config, order=orders[i]), data.fps,
                                  data.body_model.dof_names, data.body_model.name, list(data.sources), report,
                                  rng=rng, labels=labels, checkpoint=None if checkpoint is None else (save, every),
                                  resume=state if i == first else None))
    model = models[-1]
    model.growth = models[:-1]
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
    return model


def _crbm_option(name: str, **changes) -> Option:
    """The CRBM's training option ``name`` (the settings the two share are declared once), with ``changes``."""
    return replace(next(o for o in CRBM_TRAIN_OPTIONS if o.name == name), **changes)


FCRBM_TRAIN_OPTIONS = (
    Option("labels", str, None, "one style label per training clip, in clip order, comma-separated "
                                "(e.g. walk,walk,run); or read from each file: a name pattern or a CSV/TOML/JSON "
                                "file, and the key, e.g. 'dataset-2_{content}_{style}_{take}#style' (see "
                                "docs/guide/training.md)"),
    Option("unlabelled", str, None, "the label of clips that a labels pattern or file gives none (e.g. "
                                    "'normal' for clips of another corpus), which then train as one more style",
           default_note="none: such a clip is refused"),
    _crbm_option("order", default=FCRBMConfig.order, help="order N"),
    _crbm_option("hidden", default=FCRBMConfig.hidden),
    Option("factors", int, FCRBMConfig.factors, "factors per sub-model", minimum=1,
           maximum=100000),
    Option("features", int, FCRBMConfig.features, "real-valued style features", minimum=1,
           maximum=100000),
    _crbm_option("epochs", default=FCRBMConfig.epochs),
    _crbm_option("cd_k"),
    _crbm_option("batch_size"),
    _crbm_option("updates", default=FCRBMConfig.updates),
    Option("learning_rate", float, FCRBMConfig.learning_rate, "learning rate", minimum=0.0),
    Option("autoregressive_learning_rate", float, FCRBMConfig.autoregressive_learning_rate,
           "learning rate of the autoregressive and label-to-feature weights", minimum=0.0),
    _crbm_option("history_noise"),
    _crbm_option("grow_from"),
    _crbm_option("checkpoint_every"),
)


@register_prior(
    "fcrbm", summary="factored, style-gated CRBM (Taylor & Hinton 2009): every particle carries a style label; "
                     "result.json reports the posterior over the labels per frame",
    model_files="one", train=train_fcrbm_prior, train_options=FCRBM_TRAIN_OPTIONS, resumable=True,
    options=(gibbs_steps_option(30),
             *part_options(FCRBMPrior.PARTS),
             Option("style_switch", float, 0.05, "probability per frame that the style switches to another label "
                                                 "(default 0.05)", minimum=0.0, maximum=1.0),
             Option("style", str, None, "give every particle this label and never switch (the oracle), or a "
                                        "schedule walk,run@120 (label per sequence frame, for an activity "
                                        "change); default: inferred"),
             Option("style_temperature", float, STYLE_TEMPERATURE, "mixture inference: the likelihood is raised "
                    f"to 1/T when the labels are weighed (default {STYLE_TEMPERATURE:g})", minimum=1.0,
                    maximum=1e6)))
def build_fcrbm(context: PriorContext, model_files: Sequence[Path], options: dict) -> FCRBMPrior:
    from priors.fcrbm.file import load_fcrbm
    from priors.fcrbm.model import FCRBMModel

    model = loaded(model_files[0], load_fcrbm, FCRBMModel, "FCRBM", device=context.device)
    model.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps,
                           source_of(model_files[0]))
    return FCRBMPrior([model], options["gibbs_steps"], device=context.device, style_switch=options["style_switch"],
                      style=options["style"], style_temperature=options["style_temperature"], options=options)
