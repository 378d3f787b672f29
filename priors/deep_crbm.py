"""Two-layer CRBM motion prior: a Conditional Deep Belief Network (Taylor 2009, Sec. 4.3), in torch.

Training is greedy. The first layer is the CRBM of :mod:`priors.crbm_model` (order ``N``, Gaussian visible units on the
normalised invariant features, ``H1`` binary hidden units), trained as ``train --prior crbm`` trains it (with the
lower orders it grows from). Its hidden probabilities while driven by the training data (a mean-field up-pass,
one ``H1`` vector per frame that has ``N`` frames of history) are the "fully observed" data of the second layer:
a CRBM of order ``M`` with binary visible units (``H1``) and ``H2`` binary hidden units, trained with CD-k on
windows of ``M + 1`` consecutive activations of one clip (momentum, weight decay, learning rates 1e-3 and 1e-5 for
the autoregressive ``A``, as the first layer). The past is treated as fully observed at both layers (Fig. 4.4d).

Generation (Sec. 4.3.1), for a batch of histories of ``N + M`` frames:

1. mean-field up-pass through the first layer for the last ``M`` frames (each with its own ``N`` frames of history):
   the second layer's history ``h^0_{t-M..t-1}``;
2. the second layer's visible units start as a copy of ``h^0_{t-1}``; alternating Gibbs sampling in the second
   layer (binary top-level hidden samples, visible probabilities; the top-level probabilities on the final step);
3. a mean-field down-pass through the first layer: ``v_t = a_hat^0 + W^0 h^0_t`` with the first layer's dynamic
   generative bias from ``v_{t-N..t-1}``.

As a tracking prior (``deep-crbm``) the pose step and the parts are the CRBM prior's (:class:`priors.crbm.CRBMPrior`): with fewer
than ``N + M`` real history frames the first layer alone (and the lower orders its file carries) draws the pose,
so the history grows through the lower orders first (Sec. 6.4).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, ClassVar, Sequence

import numpy as np

from priors.common import gibbs_steps_option, loaded, read_model_file, source_of, torch_generator, torch_save_atomic
from priors.crbm import CRBMPrior, learned_parts
from priors.parts import GroundDiffusion, HeightOffset, PostureOffset
from priors.settings import CRBM_TRAIN_OPTIONS, ContrastiveConfig
from tracker.core.errors import InputError
from tracker.engine.prior import PriorState
from tracker.engine.registry import Option, PriorContext, TrainingData, register_prior, resolve_options

if TYPE_CHECKING:  # torch and the first layer's model load when the prior is built or trained, not when it registers
    import torch

    from priors.crbm_model import CRBM, CRBMModel

FORMAT = "pose-tracker deep-crbm v1"


@dataclass
class TopConfig(ContrastiveConfig):
    """Settings of the second layer: :class:`~priors.settings.ContrastiveConfig`'s, with a smaller second layer."""

    order: int = 2
    hidden: int = 100
    epochs: int = 200

    KIND: ClassVar[str] = "deep CRBM top"


def first_layer_activations(model: CRBMModel, clips: Sequence[np.ndarray]) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean-field hidden probabilities ``M x H1`` of the first layer driven by the clips (one row per frame with
    ``N`` frames of history, clips concatenated), and a bool ``(M,)`` that is true where a row continues the
    previous row's clip (the next frame of the same clip)."""
    import torch

    from priors.contrastive import window_index
    from priors.crbm_training import make_windows

    data = make_windows(clips, model.order, model.dof_names, model.normaliser)
    crbm, N, K = model.crbm, model.order, model.crbm.n_visible
    idx = window_index(data.starts, N + 1).to(crbm.W.device)
    window = data.frames.to(crbm.W.device)[idx]
    with torch.no_grad():
        _, b_hat = crbm.biases(window[:, :-1].reshape(len(idx), N * K))
        acts = crbm.hidden_probabilities(window[:, -1], b_hat)
    follows = torch.zeros(len(idx), dtype=torch.bool)
    follows[1:] = data.starts[1:] == data.starts[:-1] + 1
    return acts, follows


def deep_gibbs(bottom: CRBM, top: CRBM, history: torch.Tensor, steps: int, generator: torch.Generator | None
               ) -> torch.Tensor:
    """Next frames ``B x K`` from histories ``B x ((N + M) K)`` (oldest first) by the up-pass, the second layer's
    Gibbs sampling and the down-pass of the module docstring."""
    import torch

    from priors.crbm_model import bernoulli_

    B, N, M, K, H1 = len(history), bottom.order, top.order, bottom.n_visible, bottom.n_hidden
    frames = history.reshape(B, N + M, K)
    win = torch.stack([frames[:, j:N + j + 1] for j in range(M)], dim=1)  # B x M x (N+1) x K
    _, b1 = bottom.biases(win[:, :, :-1].reshape(B * M, N * K))
    acts = bottom.hidden_probabilities(win[:, :, -1].reshape(B * M, K), b1).reshape(B, M * H1)
    a2, b2 = top.biases(acts)
    h0 = acts[:, -H1:]
    for step in range(steps):
        q = top.hidden_probabilities(h0, b2)
        h1 = q if step == steps - 1 else bernoulli_(q, generator)  # q is not needed again
        h0 = torch.sigmoid(a2 + h1 @ top.W.T)
    a1, _ = bottom.biases(frames[:, M:].reshape(B, N * K))
    return a1 + h0 @ bottom.W.T


def train_top(acts: torch.Tensor, follows: torch.Tensor, config: TopConfig, rng: np.random.Generator,
              progress: Callable[[int, float], None] | None = None) -> tuple[CRBM, list[float]]:
    """The second layer: a CRBM with binary visible units on the activations ``M x H1`` (windows of ``order + 1``
    consecutive rows of one clip), trained with CD-k (binary hidden samples drive the reconstructions, hidden
    probabilities in both phases' statistics); returns it and the reconstruction error per epoch."""
    import torch

    from priors.contrastive import finish_epoch, minibatches, momentum_step, window_index
    from priors.crbm_model import CRBM, bernoulli

    cfg = config.check()
    device = acts.device
    g = torch_generator(rng, device)
    H1, N = acts.shape[1], cfg.order
    run = torch.ones(len(acts), dtype=torch.long)  # length of the run of consecutive rows ending at each row
    for i in range(1, len(acts)):
        run[i] = run[i - 1] + 1 if follows[i] else 1
    ends = torch.nonzero(run >= N + 1).flatten()
    if len(ends) == 0:
        raise InputError(f"the training clips are too short for a second layer of order {N} on top of the first")
    starts = (ends - N).to(device)
    top = CRBM(H1, cfg.hidden, N, generator=g, device=device)
    velocity = {k: torch.zeros_like(v) for k, v in top.params().items()}
    rates = {k: cfg.autoregressive_learning_rate if k == "A" else cfg.learning_rate for k in CRBM.PARAMS}
    errors: list[float] = []
    for epoch in range(cfg.epochs):
        err_sum, count = 0.0, 0
        for batch in minibatches(starts, cfg.batch_size, g):
            w = acts[window_index(batch, N + 1)]
            v0, n = w[:, -1], len(batch)
            hist = w[:, :-1].reshape(n, N * H1)
            a_hat, b_hat = top.biases(hist)
            p0 = top.hidden_probabilities(v0, b_hat)
            h = bernoulli(p0, g)
            for _ in range(cfg.cd_k):
                vk = torch.sigmoid(a_hat + h @ top.W.T)
                pk = top.hidden_probabilities(vk, b_hat)
                h = bernoulli(pk, g)
            dv, dh = v0 - vk, p0 - pk
            grads = {"W": (v0.T @ p0 - vk.T @ pk) / n, "A": hist.T @ dv / n, "B": hist.T @ dh / n,
                     "a": dv.mean(0), "b": dh.mean(0)}
            params = top.params()
            momentum_step(params, velocity, grads, rates, cfg.momentum, cfg.weight_decay, CRBM.DECAYED)
            top.set_params(params)
            err_sum += float((dv ** 2).sum())
            count += n * H1
        finish_epoch(errors, err_sum, count, epoch, "deep CRBM (second layer)", progress)
    return top, errors


@dataclass
class DeepCRBMModel:
    """The first layer (a :class:`priors.crbm.CRBMModel`, with the lower orders it grows from) and the second."""

    bottom: CRBMModel
    top: CRBM
    top_config: TopConfig
    reconstruction_errors: list[float] = field(default_factory=list)
    training_seconds: float = 0.0

    @property
    def order(self) -> int:
        """History frames the two layers need together (``N + M``)."""
        return self.bottom.order + self.top.order

    @property
    def normaliser(self):
        """The first layer's feature normaliser (the features both layers see)."""
        return self.bottom.normaliser

    @property
    def pose_step_rms(self) -> np.ndarray:
        return self.bottom.pose_step_rms

    def summary(self) -> str:
        errs = self.reconstruction_errors
        top = f"second layer error {errs[0]:.4f} -> {errs[-1]:.4f}, " if errs else ""
        return (f"deep CRBM: first layer {self.bottom.summary()}; second layer order {self.top.order}, "
                f"{self.top.n_hidden} hidden units: {top}{self.training_seconds:.1f} s")

    def save(self, path: str | Path, overwrite: bool = False) -> None:
        """The model file at ``path`` (written atomically: never half-written); an existing one is refused
        unless ``overwrite``."""
        torch_save_atomic(self.to_document(), Path(path), overwrite)

    def to_document(self) -> dict:
        return {"format": FORMAT, "bottom": self.bottom.to_document(), "top": self.top.state_dict(),
                "top_config": asdict(self.top_config),
                "reconstruction_errors": [float(e) for e in self.reconstruction_errors],
                "training_seconds": float(self.training_seconds)}

    def check_compatible(self, body_model: str, dof_names: Sequence[str], fps: float | None,
                         source: str | Path | None = None) -> None:
        self.bottom.check_compatible(body_model, dof_names, fps, source)


def load_deep_crbm(path: str | Path, device: str = "cpu") -> DeepCRBMModel:
    """A deep CRBM model file, every part checked (the first layer as a CRBM model file is); a damaged file is an
    :class:`InputError` naming it."""
    import torch

    from priors.crbm_file import model_from_document
    from priors.crbm_model import CRBM

    path = Path(path)
    doc = read_model_file(path, FORMAT, "deep CRBM")
    try:
        bottom = model_from_document(doc["bottom"], path, device)
        if bottom.pace_label is not None:
            raise InputError("deep CRBM's first layer has a pace input, which the deep prior does not use", path)
        unknown = sorted(set(doc["top_config"]) - set(TopConfig.__dataclass_fields__))
        if unknown:
            raise InputError(f"deep CRBM model file has unknown settings {', '.join(unknown)}", path)
        cfg = TopConfig(**doc["top_config"]).check()
        params, H1, N = doc["top"], bottom.crbm.n_hidden, cfg.order
        if not isinstance(params.get("W"), torch.Tensor) or params["W"].ndim != 2:
            raise InputError("deep CRBM second-layer weight W must be a 2-D tensor", path)
        H2 = params["W"].shape[1]
        expected = {"W": (H1, H2), "A": (N * H1, H1), "B": (N * H1, H2), "a": (H1,), "b": (H2,)}
        for k, shape in expected.items():
            if not isinstance(params.get(k), torch.Tensor) or tuple(params[k].shape) != shape:
                raise InputError(f"deep CRBM second-layer weight {k} must have shape {shape} (order {N} on "
                                 f"{H1} first-layer hidden units)", path)
            if not torch.all(torch.isfinite(params[k])):
                raise InputError(f"deep CRBM second-layer weight {k} contains NaN or infinite values", path)
        top = CRBM(H1, H2, N, device=device)
        top.load_state_dict(params)
        return DeepCRBMModel(bottom, top, cfg, [float(e) for e in doc["reconstruction_errors"]],
                             float(doc["training_seconds"]))
    except InputError:
        raise
    except KeyError as exc:
        raise InputError(f"deep CRBM model file lacks {exc.args[0]!r}", path) from None
    except (TypeError, ValueError, AttributeError, RuntimeError, IndexError) as exc:
        raise InputError(f"deep CRBM model file is malformed ({type(exc).__name__}: {str(exc)[:100]})",
                         path) from None


class DeepCRBMPrior(CRBMPrior):
    """Samples every particle's next pose through both layers once ``N + M`` history frames are real poses, and
    with the first layer (or the lower orders its file carries) before; the pose step, the parts and the
    per-particle state are the CRBM prior's."""

    name = "deep-crbm"

    def __init__(self, model: DeepCRBMModel, gibbs_steps: int = 30, *, device: str = "cpu",
                 ground: GroundDiffusion = GroundDiffusion(), height: HeightOffset | None = None,
                 posture: PostureOffset | None = None):
        from priors.crbm_model import CRBM

        super().__init__([model.bottom], gibbs_steps, device=device, ground=ground, height=height, posture=posture)
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

        with torch.no_grad():
            return deep_gibbs(self.deep.bottom.crbm, self.deep.top, conditioning, self.gibbs_steps, generator)

    def label_for(self, available: int) -> str:
        if available >= self.deep.order:
            return f"deep crbm order {self.deep.bottom.order}+{self.deep.top.order}"
        return f"crbm order {self.model_for(available).order}"


def train_deep_crbm_prior(data: TrainingData, options: dict, rng: np.random.Generator,
                          progress: Callable[[int, int, dict], None] | None = None,
                          checkpoint: Path | None = None) -> DeepCRBMModel:
    """``train --prior deep-crbm``: the first layer as ``train --prior crbm`` trains it, then the second layer on
    its hidden activations."""
    from priors.crbm_training import growth_orders, train_crbm_prior

    t0 = time.perf_counter()
    crbm_options = {o.name for o in CRBM_TRAIN_OPTIONS}
    bottom_options = resolve_options("training crbm", CRBM_TRAIN_OPTIONS,
                                     {k: v for k, v in options.items() if k in crbm_options and v is not None})
    bottom_options["checkpoint_every"] = None
    bottom_options["pace_input"] = False  # the second layer is trained on, and samples through, a plain first layer
    top_cfg = TopConfig(order=options["top_order"], hidden=options["top_hidden"], epochs=options["top_epochs"],
                        cd_k=bottom_options["cd_k"], batch_size=bottom_options["batch_size"]).check()
    stages = 1 + len(growth_orders(bottom_options["grow_from"], bottom_options["order"]))
    total = bottom_options["epochs"] * stages + top_cfg.epochs
    bottom = train_crbm_prior(data, bottom_options, rng, None if progress is None else
                              (lambda done, _, metrics: progress(done, total, metrics)))
    acts, follows = first_layer_activations(bottom, list(data.clips))
    before = total - top_cfg.epochs
    top, errors = train_top(acts, follows, top_cfg, rng, None if progress is None else
                            (lambda epoch, err: progress(before + epoch, total, {"second layer": err})))
    return DeepCRBMModel(bottom, top, top_cfg, errors, time.perf_counter() - t0)


DEEP_TRAIN_OPTIONS = tuple(o for o in CRBM_TRAIN_OPTIONS if o.name not in ("checkpoint_every", "pace_input")) + (
    Option("top_order", int, TopConfig.order, "order M of the second layer (default 2)", minimum=1, maximum=100),
    Option("top_hidden", int, TopConfig.hidden, "hidden units of the second layer (default 100)", minimum=1,
           maximum=100000),
    Option("top_epochs", int, TopConfig.epochs, "epochs of the second layer (default 200)", minimum=1,
           maximum=1000000),
)


@register_prior(
    "deep-crbm", summary="two-layer CRBM (Taylor 2009, Sec. 4.3): a second CRBM on the first one's hidden units",
    model_files="one", train=train_deep_crbm_prior, train_options=DEEP_TRAIN_OPTIONS,
    options=(gibbs_steps_option(30), *GroundDiffusion.OPTIONS, *HeightOffset.OPTIONS, *PostureOffset.OPTIONS))
def build_deep_crbm(context: PriorContext, model_files: Sequence[Path], options: dict) -> DeepCRBMPrior:
    model = loaded(model_files[0], load_deep_crbm, DeepCRBMModel, "deep CRBM", device=context.device)
    model.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps,
                           source_of(model_files[0]))
    return DeepCRBMPrior(model, options["gibbs_steps"], device=context.device, **learned_parts(options, paced=False))
