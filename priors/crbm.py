"""Conditional Restricted Boltzmann Machine motion prior (Taylor 2009, Ch. 4 and Sec. 6.3-6.4), in torch.

Model (Gaussian visible units with unit variance on normalised data, binary
hidden units, order N)::

    a_hat = a + A^T v_<t          b_hat = b + B^T v_<t          (eqs. 4.4, 4.7)
    p(h_j = 1 | v_t, v_<t) = sigmoid(b_hat_j + sum_i W_ij v_i,t)  (eq. 4.5)
    p(v_t | h_t, v_<t) = N(a_hat + W h_t, I)                      (eq. 4.6)
    F(v_t | v_<t) = 1/2 |v_t - a_hat|^2 - sum_j softplus(W_j^T v_t + b_hat_j)   (eq. 4.18)

``v_<t`` is the history, the N previous frames concatenated oldest first
(``N*K`` numbers for K features). Data are the invariant features of
:mod:`tracker.core.representation`, normalised by a :class:`FeatureNormaliser`
(constant dimensions dropped).

Training: CD-k on mini-batches of randomly permuted (N+1)-frame windows, built
by indexing (frames are never copied into windows), with momentum, weight
decay on W, A and B, learning rate 1e-3 (1e-5 for the autoregressive A), the
mean-field approximations of Sec. 4.2.4 (expected visible values; binary hidden
states driving reconstructions and the positive statistics, hidden
probabilities in the negative statistics), Gaussian noise on the history
(Sec. 6.4.1; by default per dimension the 99th percentile of the frame-to-frame
change) and an optional sparsity target (Sec. 4.5.4, cross-entropy to a damped
average activation). One ``torch.Generator``, seeded from the numpy generator passed in, drives every random
draw.

Generation (Sec. 4.2.3): alternating Gibbs sampling from ``v = v_{t-1}``, with
binary hidden samples, expected visible values and hidden probabilities on the
final step. "Best guess" prediction descends the free energy (eq. 4.19).

Registered as the ``crbm`` prior (``train`` and ``track --prior crbm``).
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, ClassVar, Sequence

import numpy as np
import torch

from priors.common import (
    GROUND_VELOCITY_OPTION, GROUND_VELOCITY_PULL_OPTION, HEADING_NOISE_OPTION, HEIGHT_DRIFT_OPTION,
    HEIGHT_SPREAD_HELP, HEIGHT_SPREAD_OPTION, ROOT_NOISE_MM, ROOT_NOISE_OPTION, HeightOffsets, TrainedModel,
    UNLEARNED_MOTION_OPTIONS, add_ground_diffusion, add_heading_diffusion, check_weights, checked_data_settings,
    checked_fraction_per_frame, checked_ground_velocity, checked_time_warp, gaussian_drift, gaussian_start,
    gibbs_steps_option, mix_in_random_walk, normaliser_from_tensors, persist_ground_step, read_model_file, robust_share,
    scale_ground_steps, shift_height, steps_taken, time_warp_note, torch_generator,
    torch_save_atomic,
)
from priors.contrastive import ContrastiveConfig, finish_epoch, minibatches, momentum_step
from priors.ensemble import EnsemblePrior
from tracker.core.errors import InputError
from tracker.core.representation import (
    PACE_FLOOR_MM, STANDING_LOG_PACE, STEP_FEATURES, FeatureNormaliser, clip_features, clip_log_pace, log_pace,
    next_poses, pending_step, poses_to_invariant, posture_features, step_rms,
)
from tracker.engine.prior import MotionPrior, PriorState
from tracker.engine.registry import Option, PriorContext, TrainingData, register_prior

FORMAT = "pose-tracker crbm v1"
#: Training checkpoints have their own format, so a half-trained model is never taken for a model file.
CHECKPOINT_FORMAT = "pose-tracker crbm training checkpoint v1"
@dataclass
class CRBMConfig(ContrastiveConfig):
    """Training settings of a CRBM: :class:`~priors.contrastive.ContrastiveConfig`'s, and the CRBM's own."""

    history_noise: float | str = "auto"
    sparsity_target: float | None = None
    sparsity_cost: float = 0.1
    #: Condition on each frame's pace (:func:`~tracker.core.representation.clip_log_pace`, one extra input before
    #: the history), so that one model walks at every pace it was shown, at the pace the tracker gives it.
    pace_input: bool = False
    #: Learn the root height above each training subject's standing root height (its body model's
    #: ``rest_root_height``) instead of above the floor, and predict it above the tracked person's: one model then
    #: fits people of other sizes (:func:`heights_above_standing`).
    standing_height: bool = False
    #: Fraction of each clip (its last frames) held out to choose the epoch: every ``validation_every`` epochs the
    #: one-step prediction error (free-energy best guess, normalised units) on the held-out windows is measured and
    #: the weights of the best check are kept (Taylor 2009 held out 10%). 0: no validation, the last epoch's weights.
    validation: float = 0.0
    validation_every: int = 10
    #: Std (rad) of a random constant added to every posture angle (the root's pitch and roll, every joint angle)
    #: of each training window, its history and the frame to predict alike, drawn afresh for every window of every
    #: epoch (:func:`posture_offset_scale`): people hold their joints differently, and a model shown only its
    #: training subjects' postures pulls an unseen person's toward them within one frame; shown shifted postures, it
    #: learns that a posture held in the history persists. 0: off.
    posture_offset: float = 0.0

    def check(self) -> "CRBMConfig":
        super().check()
        if self.sparsity_target is not None and not 0 < self.sparsity_target < 1:
            raise InputError(f"sparsity target must lie in (0, 1), got {self.sparsity_target}")
        if not 0 <= self.validation <= 0.5:
            raise InputError(f"validation fraction must lie in [0, 0.5], got {self.validation}")
        if int(self.validation_every) < 1:
            raise InputError(f"validation_every must be at least 1, got {self.validation_every}")
        if isinstance(self.posture_offset, bool) or not isinstance(self.posture_offset, (int, float)) \
                or not 0 <= self.posture_offset <= math.pi:
            raise InputError(f"posture offset must lie in [0, pi] rad, got {self.posture_offset!r}")
        return self


#: The training settings that change what a model's inputs mean (name: what it is, for messages): the growth
#: models in a file and a resumed training must agree with the model on them.
INPUT_SETTINGS = {"pace_input": "pace input", "standing_height": "height reference"}


def uniform16(shape: tuple[int, ...], generator: torch.Generator | None, device: torch.device | str) -> torch.Tensor:
    """Uniform random integers of ``shape`` as int16 (each of -2^15 .. 2^15 - 1 equally likely): four from every
    64-bit draw of ``generator``, about three times faster on CPU than as many float uniforms from ``torch.rand``
    (whose generator makes one 32-bit draw per number)."""
    n = math.prod(shape)
    words = torch.empty((n + 3) // 4, dtype=torch.int64, device=device)
    words.random_(-2 ** 63, 2 ** 63 - 1, generator=generator)
    return words.view(torch.int16)[:n].view(shape)


def below_(u: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """Binary samples (0 or 1 in ``p``'s dtype) written over the probabilities ``p``, in place, from the uniform
    integers ``u`` (:func:`uniform16`, same shape): 1 where ``u + 2^15`` (uniform on 0 .. 2^16 - 1) is below
    ``p * 2^16``, so a unit is on with probability ``p`` to within 2^-16 (float32 or float64 ``p``; the threshold
    ``p * 2^16 - 2^15`` is rounded in ``p``'s dtype, which moves it by at most 2^-8 in float32)."""
    return torch.lt(u, p.mul_(65536.0).sub_(32768.0), out=p)


def bernoulli_(p: torch.Tensor, generator: torch.Generator | None) -> torch.Tensor:
    """Binary samples (0 or 1 in ``p``'s dtype) with probabilities ``p``, written over ``p``: :func:`below_` on
    :func:`uniform16` integers (several times faster than ``torch.bernoulli`` with an explicit generator on CPU,
    and than converting a boolean comparison)."""
    return below_(uniform16(p.shape, generator, p.device), p)


def bernoulli(p: torch.Tensor, generator: torch.Generator | None) -> torch.Tensor:
    """As :func:`bernoulli_`, with ``p`` left unchanged."""
    return bernoulli_(p.clone(), generator)


class CRBM:
    """Parameters and inference of one CRBM (float32 tensors on one device).

    With ``n_context`` > 0 the conditioning input is ``n_context`` numbers (the pace) followed by the history,
    ``B x (n_context + N K)``; they drive the dynamic biases through the first rows of ``A`` and ``B``."""

    def __init__(self, n_visible: int, n_hidden: int, order: int, generator: torch.Generator | None = None,
                 device: str | torch.device = "cpu", n_context: int = 0):
        self.n_visible, self.n_hidden, self.order, self.n_context = n_visible, n_hidden, order, n_context
        self.device = torch.device(device)
        g = generator
        kw = {"device": self.device, "dtype": torch.float32}
        inputs = n_context + order * n_visible
        self.W = 0.01 * torch.randn(n_visible, n_hidden, generator=g, **kw)
        self.A = 0.01 * torch.randn(inputs, n_visible, generator=g, **kw)
        self.B = 0.01 * torch.randn(inputs, n_hidden, generator=g, **kw)
        self.a = torch.zeros(n_visible, **kw)
        self.b = torch.zeros(n_hidden, **kw)

    PARAMS = ("W", "A", "B", "a", "b")
    #: The parameters weight decay applies to (the weights, not the biases).
    DECAYED = ("W", "A", "B")

    def params(self) -> dict[str, torch.Tensor]:
        """The parameter tensors by name (the tensors themselves, for an update; see :meth:`set_params`)."""
        return {k: getattr(self, k) for k in self.PARAMS}

    def set_params(self, params: dict[str, torch.Tensor]) -> None:
        """Take updated parameter tensors (by name, as :meth:`params` gives them)."""
        for k, v in params.items():
            setattr(self, k, v)

    def state_dict(self) -> dict[str, torch.Tensor]:
        return {k: getattr(self, k).detach().cpu().clone() for k in self.PARAMS}

    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        for k in self.PARAMS:
            setattr(self, k, state[k].to(self.device, torch.float32))

    def biases(self, history: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Dynamic biases ``a_hat`` ``B x K`` and ``b_hat`` ``B x H`` from histories ``B x (C + N K)`` (the context
        first, see the class docstring)."""
        return self.a + history @ self.A, self.b + history @ self.B

    def hidden_probabilities(self, v: torch.Tensor, b_hat: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(v @ self.W + b_hat)


    def free_energy(self, v: torch.Tensor, history: torch.Tensor) -> torch.Tensor:
        """Free energy ``(B,)`` of frames ``v`` ``B x K`` given histories (eq. 4.18)."""
        a_hat, b_hat = self.biases(history)
        return 0.5 * ((v - a_hat) ** 2).sum(-1) - torch.nn.functional.softplus(v @ self.W + b_hat).sum(-1)

    def gibbs(self, history: torch.Tensor, steps: int, generator: torch.Generator | None,
              init: torch.Tensor | None = None) -> torch.Tensor:
        """Next frames ``B x K`` by alternating Gibbs sampling from ``init`` (default: the last history frame).

        Binary hidden samples, expected visible values; the final visible update uses the hidden
        probabilities (Sec. 4.2.4).
        """
        a_hat, b_hat = self.biases(history)
        v = history[:, -self.n_visible:] if init is None else init
        for step in range(steps):
            p = self.hidden_probabilities(v, b_hat)
            h = p if step == steps - 1 else bernoulli_(p, generator)  # p is not needed again
            v = a_hat + h @ self.W.T
        return v

    def best_guess(self, history: torch.Tensor, iterations: int = 30, init: torch.Tensor | None = None
                   ) -> torch.Tensor:
        """The frame minimising the free energy given the history (eq. 4.19), by L-BFGS from ``init``."""
        a_hat, b_hat = (x.detach() for x in self.biases(history))
        v = (history[:, -self.n_visible:] if init is None else init).detach().clone(
            memory_format=torch.contiguous_format).requires_grad_(True)
        opt = torch.optim.LBFGS([v], lr=1.0, max_iter=iterations, line_search_fn="strong_wolfe")

        def closure():
            opt.zero_grad()
            f = (0.5 * ((v - a_hat) ** 2).sum() - torch.nn.functional.softplus(v @ self.W + b_hat).sum())
            f.backward()
            return f

        opt.step(closure)
        return v.detach()


# ---------------------------------------------------------------------------
# Training data
# ---------------------------------------------------------------------------

@dataclass
class WindowData:
    """Normalised features of all training clips, concatenated ``T x K``, and the start indices ``(M,)`` of
    every (N+1)-frame window that lies inside one clip and avoids each clip's last frame (whose velocities
    are only a repeat of the step before)."""

    frames: torch.Tensor
    starts: torch.Tensor
    normaliser: FeatureNormaliser
    #: Each frame's log pace ``(T,)`` (:func:`~tracker.core.representation.clip_log_pace`), when asked for.
    pace: np.ndarray | None = None


def make_windows(clips: Sequence[np.ndarray], order: int, dof_names: Sequence[str],
                 normaliser: FeatureNormaliser | None = None, pace_window: int | None = None) -> WindowData:
    """The training windows of ``clips``; with ``pace_window`` (frames) also every frame's log pace."""
    normed, normaliser = clip_features(clips, dof_names, normaliser)
    pace = None if pace_window is None else np.concatenate([clip_log_pace(c, pace_window) for c in clips])
    starts, offset = [], 0
    for f in normed:
        n = len(f) - order
        if n > 0:
            starts.append(offset + np.arange(n))
        offset += len(f)
    if not starts:
        raise InputError(f"the training clips are too short for order {order} (need more than {order + 2} frames)")
    return WindowData(torch.tensor(np.concatenate(normed), dtype=torch.float32),
                      torch.tensor(np.concatenate(starts)), normaliser, pace)


def heights_above_standing(clips: Sequence[np.ndarray], standing_heights: Sequence[float] | None) -> list[np.ndarray]:
    """The clips (each ``T x D`` poses) with each one's root height (mm) taken relative to its subject's standing
    root height ``standing_heights[i]`` (mm): people of different sizes walk at different absolute heights but at
    much the same height below their own standing height (the shared walks: 12-50 mm below it, against absolute
    means of 868-978 mm)."""
    if standing_heights is None or len(standing_heights) != len(clips):
        raise InputError("training for the height above standing needs each clip's standing root height (clips "
                         "retargeted to body models of their own subjects, as train reads them from mocap files)")
    heights = np.asarray(standing_heights, float)
    if not np.all(np.isfinite(heights) & (heights > 0)):
        raise InputError(f"standing root heights must be positive mm, got {heights.tolist()}")
    # A pose's root height is number 2, as an invariant feature's is.
    return [shift_height(np.array(clip, float)[None], np.array([-h]))[0] for clip, h in zip(clips, heights)]


def posture_offset_scale(normaliser: FeatureNormaliser, std: float) -> torch.Tensor:
    """Per kept feature ``(K,)``, the std in normalised units of a posture offset of ``std`` rad
    (:attr:`CRBMConfig.posture_offset`): ``std`` over the feature's std for the posture angles (the root's pitch
    and roll, every joint angle), 0 for the ground steps, the height and the heading rate."""
    scale = np.zeros(len(normaliser.names))
    posture = posture_features(len(normaliser.names))
    scale[posture] = std / normaliser.std[posture]
    return torch.tensor(scale[normaliser.keep], dtype=torch.float32)


def history_noise_scale(data: WindowData) -> torch.Tensor:
    """Per-dimension noise for the history: the 99th percentile of |frame-to-frame change| in the data."""
    idx = data.starts
    diffs = (data.frames[idx + 1] - data.frames[idx]).abs()
    return torch.quantile(diffs, 0.99, dim=0)


# ---------------------------------------------------------------------------
# The trained model: CRBM + normaliser + the settings it was trained with
# ---------------------------------------------------------------------------

@dataclass(kw_only=True)
class CRBMModel(TrainedModel):
    """A trained CRBM: its weights and settings, the lower orders it grows from, and what
    :class:`~priors.common.TrainedModel` keeps."""

    crbm: CRBM
    config: CRBMConfig
    #: Lower-order CRBMs trained with this one on the same data, that grow the history from the known
    #: frames until this model's order is reached (Taylor 2009, Sec. 6.4); saved in the same file.
    growth: list["CRBMModel"] = field(default_factory=list)
    #: With ``config.pace_input``: the mean and std of the training frames' log pace, which normalise the pace
    #: input (:func:`~tracker.core.representation.clip_log_pace`); None otherwise.
    pace_label: tuple[float, float] | None = None
    #: With ``config.validation``: ``[epoch, held-out one-step error]`` of every check, and the epoch whose
    #: weights the model kept (0: no validation).
    validation_errors: list[list[float]] = field(default_factory=list)
    best_epoch: int = 0

    KIND: ClassVar[str] = "CRBM"

    @property
    def order(self) -> int:
        return self.crbm.order

    @property
    def standing_height(self) -> bool:
        """Whether the model's root heights are above the subject's standing root height (else above the floor)."""
        return self.config.standing_height

    def pace_input(self, log_paces: np.ndarray) -> np.ndarray:
        """The normalised pace input ``(P, 1)`` for log paces ``(P,)``."""
        mean, std = self.pace_label
        return ((np.asarray(log_paces, float) - mean) / std)[:, None]

    def summary(self) -> str:
        """One line on how training went."""
        fit = self.fit_note()
        grow = f" (grows from order {', '.join(str(g.order) for g in self.growth)})" if self.growth else ""
        pace = "" if self.pace_label is None else \
            f", paced (training paces {np.exp(self.pace_label[0]) - PACE_FLOOR_MM:.1f} mm/frame typical)"
        height = ", heights above standing" if self.standing_height else ""
        if self.best_epoch:
            best = min(e for _, e in self.validation_errors)
            fit += f"held-out one-step error {best:.4f} at epoch {self.best_epoch} (kept), "
        return (f"CRBM order {self.order}{grow}, {self.crbm.n_hidden} hidden units{time_warp_note(self.time_warp)}"
                f"{pace}{height}: "
                f"{fit}{self.training_seconds:.1f} s")

    def to_document(self) -> dict:
        """The model file's dictionary (tensors and plain values; ``torch.load(weights_only=True)`` reads it)."""
        config = asdict(self.config)
        # Settings at their defaults are left out, as in files written before they existed (readable by those).
        for key in ("standing_height", "validation", "validation_every", "posture_offset"):
            if config[key] == getattr(CRBMConfig, key):
                del config[key]
        return {
            "format": FORMAT, "params": self.crbm.state_dict(), "config": config, **self.data_document(),
            "validation_errors": [[float(e), float(x)] for e, x in self.validation_errors],
            "best_epoch": int(self.best_epoch), "growth": [g.to_document() for g in self.growth],
            "pace_label": None if self.pace_label is None else [float(x) for x in self.pace_label],
        }


def load_crbm(path: str | Path, device: str = "cpu") -> CRBMModel:
    """A CRBM model file (with the lower-order models it grows from), every part checked: a missing key, a
    weight of the wrong shape, a non-finite weight or normaliser, or an unknown setting is an InputError
    naming the file."""
    path = Path(path)
    return _model_from_document(read_model_file(path, FORMAT, "CRBM"), path, device)


def _model_from_document(doc: dict, path: Path, device: str) -> CRBMModel:
    try:
        config = dict(doc["config"])
        config.pop("seed", None)  # files written before the generator came from the caller
        unknown = sorted(set(config) - set(CRBMConfig.__dataclass_fields__))
        if unknown:
            raise InputError(f"CRBM model file has unknown settings {', '.join(unknown)}", path)
        try:
            cfg = CRBMConfig(**config).check()
        except (TypeError, ValueError) as exc:
            raise InputError(f"CRBM model file has bad settings ({exc})", path) from None
        params = doc["params"]
        if not isinstance(params, dict) or any(not isinstance(params.get(k), torch.Tensor) for k in CRBM.PARAMS):
            raise InputError(f"CRBM model file lacks weights {', '.join(CRBM.PARAMS)}", path)
        if params["W"].ndim != 2:
            raise InputError(f"CRBM weight W must be 2-D, got shape {tuple(params['W'].shape)}", path)
        K, H = params["W"].shape
        N = cfg.order
        pace_label = _checked_pace_label(doc.get("pace_label"), cfg.pace_input, path)
        C = int(cfg.pace_input)
        expected = {"W": (K, H), "A": (C + N * K, K), "B": (C + N * K, H), "a": (K,), "b": (H,)}
        check_weights(params, expected, "CRBM weight", f"order {N} with {K} visible and {H} hidden units"
                      f"{' and a pace input' if C else ''}", path)
        crbm = CRBM(K, H, N, device=device, n_context=C)
        crbm.load_state_dict(params)
        normaliser = normaliser_from_tensors(doc["normaliser"], path)
        if normaliser.n_kept != K:
            raise InputError(f"model has {K} visible units but its normaliser keeps {normaliser.n_kept}", path)
        fps, body_model, dof_names, sources, step = checked_data_settings(doc, "CRBM", path)
        growth = [_model_from_document(g, path, device) for g in doc.get("growth", [])]
        for key, what in INPUT_SETTINGS.items():
            if any(getattr(g.config, key) != getattr(cfg, key) for g in growth):
                raise InputError(f"CRBM model file's growth models and main model differ in {what}", path)
        return CRBMModel(crbm=crbm, normaliser=normaliser, config=cfg, fps=fps, body_model=body_model,
                         dof_names=dof_names, sources=sources, pose_step_rms=step,
                         reconstruction_errors=[float(e) for e in doc["reconstruction_errors"]],
                         training_seconds=float(doc["training_seconds"]), growth=growth,
                         time_warp=checked_time_warp(doc.get("time_warp"), "CRBM", path), pace_label=pace_label,
                         validation_errors=[[float(e), float(x)] for e, x in doc.get("validation_errors", [])],
                         best_epoch=int(doc.get("best_epoch", 0)))
    except InputError:
        raise
    except KeyError as exc:
        raise InputError(f"CRBM model file lacks {exc.args[0]!r}", path) from None
    except (TypeError, ValueError, AttributeError, RuntimeError) as exc:
        raise InputError(f"CRBM model file is malformed ({type(exc).__name__}: {str(exc)[:100]})", path) from None


def _checked_pace_label(value, pace_input: bool, path: Path) -> tuple[float, float] | None:
    """A model file's ``pace_label`` (mean and std of the training log paces), present exactly when the model
    was trained with a pace input; anything else is an InputError naming the file."""
    if not pace_input:
        if value is not None:
            raise InputError("CRBM model file has a pace_label but was not trained with a pace input", path)
        return None
    if not isinstance(value, (list, tuple)) or len(value) != 2 or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value) \
            or not value[1] > 0:
        raise InputError(f"CRBM model file's pace_label must be [mean, std > 0] of the training log paces, "
                         f"got {value!r}", path)
    return float(value[0]), float(value[1])


# ---------------------------------------------------------------------------
# Training
# ---------------------------------------------------------------------------

def train_crbm(clips: Sequence[np.ndarray], config: CRBMConfig, fps: float, dof_names: Sequence[str],
               body_model: str = "15-cone", sources: Sequence[str] = (),
               progress: Callable[[int, float], None] | None = None,
               checkpoint: tuple[Callable[[CRBMModel, dict], None], int] | None = None, device: str = "cpu", *,
               rng: np.random.Generator, resume: dict | None = None,
               standing_heights: Sequence[float] | None = None) -> CRBMModel:
    """Train a CRBM on pose clips (each ``T x D`` at ``fps``) with CD-k; every random draw comes from ``rng``.

    With ``config.standing_height``, ``standing_heights`` gives each clip's standing root height (mm, the
    ``rest_root_height`` of the body model it was retargeted to), and the model learns the height above it.

    ``progress(epoch, reconstruction_error)`` is called after every epoch; ``checkpoint = (save, every)``
    calls ``save(model, training_state)`` every ``every`` epochs, and ``resume`` (such a ``training_state``,
    with the model's weights in it) continues from there to the model an uninterrupted run gives.
    """
    cfg = config.check()
    t0 = time.perf_counter()
    if cfg.standing_height:
        clips = heights_above_standing(clips, standing_heights)
    g = torch_generator(rng, device)
    data = make_windows(clips, cfg.order, dof_names, pace_window=pace_window(fps) if cfg.pace_input else None)
    frames = data.frames.to(device)
    K, N, H, C = frames.shape[1], cfg.order, cfg.hidden, int(cfg.pace_input)
    crbm = CRBM(K, H, N, generator=g, device=device, n_context=C)
    noise = history_noise_scale(data).to(device) if cfg.history_noise == "auto" else \
        torch.full((K,), float(cfg.history_noise), device=device)
    noise = torch.cat([torch.zeros(C, device=device), noise.repeat(N)])  # the pace input is given, not noisy
    posture = posture_offset_scale(data.normaliser, cfg.posture_offset).to(device) if cfg.posture_offset else None
    pace_label, pace = None, None
    if cfg.pace_input:
        pace_label = (float(np.mean(data.pace)), max(float(np.std(data.pace)), 1e-3))
        pace = torch.tensor((data.pace - pace_label[0]) / pace_label[1], dtype=torch.float32, device=device)
    steps = torch.arange(N + 1, device=device)
    velocity = {k: torch.zeros_like(getattr(crbm, k)) for k in CRBM.PARAMS}
    rates = {"W": cfg.learning_rate, "A": cfg.autoregressive_learning_rate, "B": cfg.learning_rate,
             "a": cfg.learning_rate, "b": cfg.learning_rate}
    activity = torch.full((H,), cfg.sparsity_target or 0.0, device=device)
    model = CRBMModel(crbm=crbm, normaliser=data.normaliser, config=cfg, fps=fps, body_model=body_model,
                      dof_names=list(dof_names), sources=list(sources), pose_step_rms=step_rms(clips),
                      pace_label=pace_label)
    starts, held_out = split_validation(data.starts, [len(c) for c in clips], N, cfg.validation)
    starts, held_out = starts.to(device), held_out.to(device)

    def windows(window_starts: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The frames to predict ``B x K`` and their conditioning inputs ``B x (C + N K)`` (the pace of the frame
        to predict, then the history) of the windows starting at ``window_starts`` ``(B,)``: windows by indexing."""
        idx = window_starts[:, None] + steps  # B x (N+1) frame indices
        window = frames[idx]
        hist = window[:, :-1].reshape(len(idx), N * K)
        if pace is not None:
            hist = torch.cat([pace[idx[:, -1], None], hist], dim=1)
        return window[:, -1], hist

    def held_out_error() -> float:
        """Mean squared one-step prediction error (normalised units) of the free-energy best guess on the
        held-out windows."""
        v, hist = windows(held_out)
        return float(((crbm.best_guess(hist) - v) ** 2).mean())

    best = {"error": math.inf, "params": None}
    first_epoch, seconds_before = 0, 0.0
    if resume is not None:
        crbm.load_state_dict(resume["params"])
        velocity = {k: resume["velocity"][k].to(device) for k in CRBM.PARAMS}
        activity = resume["activity"].to(device)
        g.set_state(resume["generator"])
        first_epoch = int(resume["epoch"])
        model.reconstruction_errors = [float(e) for e in resume["reconstruction_errors"]]
        seconds_before = float(resume["seconds"])
        if "best" in resume:
            best = {"error": float(resume["best"]["error"]), "params": resume["best"]["params"]}
            model.validation_errors = [list(map(float, x)) for x in resume["best"]["errors"]]
            model.best_epoch = int(resume["best"]["epoch"])
    for epoch in range(first_epoch, cfg.epochs):
        err_sum, count = 0.0, 0
        for batch in minibatches(starts, cfg.batch_size, g):
            v0, hist = windows(batch)
            if posture is not None:  # one offset per window, on the frame to predict and every history frame
                offset = torch.randn(v0.shape, generator=g, device=device) * posture
                v0 = v0 + offset
                hist = hist + torch.cat([torch.zeros(len(v0), C, device=device), offset.repeat(1, N)], dim=1)
            if cfg.history_noise:
                hist = hist + torch.randn(hist.shape, generator=g, device=device) * noise
            a_hat, b_hat = crbm.biases(hist)
            p0 = crbm.hidden_probabilities(v0, b_hat)
            h0 = bernoulli(p0, g)
            h = h0
            for _ in range(cfg.cd_k):
                vk = a_hat + h @ crbm.W.T
                pk = crbm.hidden_probabilities(vk, b_hat)
                h = bernoulli(pk, g)
            n = len(v0)
            dv, dh = v0 - vk, h0 - pk
            grads = {"W": (v0.T @ h0 - vk.T @ pk) / n, "A": hist.T @ dv / n, "B": hist.T @ dh / n,
                     "a": dv.mean(0), "b": dh.mean(0)}
            if cfg.sparsity_target is not None:
                activity = 0.9 * activity + 0.1 * p0.mean(0)
                push = cfg.sparsity_cost * (cfg.sparsity_target - activity)
                grads["b"] = grads["b"] + push
                grads["W"] = grads["W"] + v0.mean(0)[:, None] * push[None, :]
                grads["B"] = grads["B"] + hist.mean(0)[:, None] * push[None, :]
            params = crbm.params()
            momentum_step(params, velocity, grads, rates, cfg.momentum, cfg.weight_decay, CRBM.DECAYED)
            crbm.set_params(params)
            err_sum += float(((v0 - vk) ** 2).sum())
            count += n * K
        finish_epoch(model.reconstruction_errors, err_sum, count, epoch, "CRBM", progress)
        if len(held_out) and ((epoch + 1) % cfg.validation_every == 0 or epoch + 1 == cfg.epochs):
            error = held_out_error()
            model.validation_errors.append([epoch + 1, error])
            if error < best["error"]:
                best = {"error": error, "params": crbm.state_dict()}
                model.best_epoch = epoch + 1
        if checkpoint is not None and (epoch + 1) % checkpoint[1] == 0 and epoch + 1 < cfg.epochs:
            model.training_seconds = seconds_before + time.perf_counter() - t0
            checkpoint[0](model, {"params": crbm.state_dict(), "epoch": epoch + 1,
                                  "velocity": {k: v.detach().cpu().clone() for k, v in velocity.items()},
                                  "activity": activity.detach().cpu().clone(), "generator": g.get_state(),
                                  "reconstruction_errors": list(model.reconstruction_errors),
                                  "seconds": model.training_seconds,
                                  **({"best": {**best, "errors": list(model.validation_errors),
                                               "epoch": model.best_epoch}} if len(held_out) else {})})
    if best["params"] is not None:  # the weights of the best held-out check
        crbm.load_state_dict(best["params"])
    model.training_seconds = seconds_before + time.perf_counter() - t0
    return model


def split_validation(starts: torch.Tensor, clip_lengths: Sequence[int], order: int, fraction: float
                     ) -> tuple[torch.Tensor, torch.Tensor]:
    """The training windows' starts ``(M,)`` (indices into the clips' frames concatenated, clips of
    ``clip_lengths`` frames; a window predicts the frame ``order`` after its start) split into those for training
    and those held out: windows predicting a frame in the last ``fraction`` of their clip are held out (none when
    ``fraction`` is 0). Held-out windows are whole stretches of motion rather than frames scattered between
    training frames, which would flatter the check."""
    if fraction <= 0:
        return starts, starts[:0]
    s = starts.cpu().numpy()
    held = np.zeros(len(s), bool)
    offset = 0
    for n in clip_lengths:
        held |= (s + order >= offset + int(round((1 - fraction) * n))) & (s < offset + n)
        offset += n
    if held.all() or not held.any():
        raise InputError(f"a validation fraction of {fraction:g} leaves no windows to "
                         f"{'train on' if held.all() else 'hold out'}; the clips are too short")
    return starts[torch.from_numpy(~held)], starts[torch.from_numpy(held)]


#: Least spread (std of the training frames' log pace) for which ``train`` gives a CRBM a pace input by default:
#: a 10% spread of paces. One person's walks vary by less (subject 7's four walks: 0.07; one walk: 0.01), and a
#: model trained on them could not learn what the input means; the walks of three or more of the shared subjects
#: vary by 0.14-0.58 (set a priori from these spreads, not from tracking results).
PACE_SPREAD_FOR_INPUT = 0.1


def paces_vary(clips: Sequence[np.ndarray], fps: float) -> bool:
    """Whether the clips' frames (each clip ``T x D`` at ``fps``) vary in pace enough for a pace input
    (:data:`PACE_SPREAD_FOR_INPUT`)."""
    paces = np.concatenate([clip_log_pace(c, pace_window(fps)) for c in clips])
    return bool(np.std(paces) >= PACE_SPREAD_FOR_INPUT)


def given_clips(data: TrainingData) -> list[np.ndarray]:
    """The clips as given, before ``--time-warp`` replayed them: of each given clip, its copy at the speed nearest
    1 (the clip itself when the speeds include 1). The pace input's default looks at these, so the warp alone
    does not turn it on."""
    if not data.origins:
        return list(data.clips)
    nearest = int(np.argmin(np.abs(np.asarray(data.time_warp) - 1.0)))  # copies run clip by clip, speed by speed
    return list(data.clips[nearest::len(data.time_warp)])


def pace_window(fps: float) -> int:
    """Frames of the centred window a training frame's pace is averaged over: one second."""
    return max(int(round(fps)), 1)


# ---------------------------------------------------------------------------
# As a tracking prior
# ---------------------------------------------------------------------------

#: Default Gibbs steps per sample of the CRBM prior. Chosen on the tuning folds of the leave-one-subject-out
#: protocol (folds 2 and 7, CRBM-3, 1000 particles, 5 seeds; benchmarks/experiments/leave_one_subject_out/gibbs/,
#: docs/tracking.md): 30, 10 and 5 steps gave the same error with 4 views (mean ratio to zero-velocity 0.66 each)
#: and 1.51, 1.46, 1.35 with one view (within the seeds' spread; only order 3 was measured), and 5 steps sample about
#: 5x faster than 30 (the CRBM's largest cost).
GIBBS_STEPS = 5

#: Defaults of ``pace_spread`` and ``pace_drift`` for a model trained with a pace input (``train --pace-input``):
#: the std of each particle's initial log pace around the known frames' pace, and of its change per frame.
#: Chosen a priori, before any tracking run: 0.3 covers a pace 0.55-1.8 times the known frames' within two
#: standard deviations; 0.05 per frame lets the pace move by about 0.4 (a factor 1.5) in a second at 60 Hz, the
#: time over which the training labels average.
PACED_SPREAD, PACED_DRIFT = 0.3, 0.05
#: Default ``pace_jump`` of a paced model: the probability per frame that a particle's pace is drawn afresh from
#: the training frames' paces. Added after test fold 131 (a start, a walk and a stop), where the particles' paces
#: settled at standing while the person started slowly and stayed there when he walked on, so that a particle
#: could pick up a start or a stop within a few frames. Off by default: 0.02 lost on the tuning folds (fold 7 with
#: one view: 273.6 against 189.0 mm; the other three columns within 1 mm; docs/unseen_people.md).
PACED_JUMP = 0.0
#: Default ``height_spread`` (mm) of a paced model (one trained on the walks of several people): each particle's
#: own root-height offset, Gaussian with this std at the start. Won round 18 of docs/unseen_people.md (with the
#: default annealing) on the tuning folds (mean ratio to zero-velocity 0.77 against 0.86) and on the test folds
#: (1.16 against 1.39); 50 mm was chosen before round 16's runs (the spread of the shared subjects' root heights).
PACED_HEIGHT_SPREAD = 50.0
#: Default ``posture_gain`` of a paced model: the fraction per frame of the images' mean posture correction added
#: to the posture offset (:func:`updated_posture_offset`). A gain of 0.2 won round 23 of docs/unseen_people.md
#: against none on the tuning folds (mean ratio to zero-velocity over both view counts 0.76 against 0.77) and on the
#: test folds (0.90 against 1.07, better in all six fold and view-count cells); in round 24, 0.1 won against 0.2 and
#: 0.4 on the tuning folds (0.747 against 0.754 and 0.832) and against 0.2 on the test folds (0.893 against 0.904).
PACED_POSTURE_GAIN = 0.1


def updated_posture_offset(offset: np.ndarray, posterior: np.ndarray, predicted: np.ndarray,
                           gain: float) -> np.ndarray:
    """The posture offset ``(Kp,)`` (rad, the person's posture angles minus the ones the model would give) one
    frame on: moved by ``gain`` times the innovation, the mean posture angles of the resampled particles
    ``posterior`` ``P x Kp`` minus the mean the prior predicted for them the frame before ``predicted``
    ``(Kp,)`` (NaN before the first prediction: no move). An integrator of the likelihood's corrections: a model
    that pulls an unseen person's posture toward its training subjects' is corrected by as much as the images
    keep pulling it back, and a correction that averages out over the gait (a wrong phase) leaves it alone."""
    if not np.all(np.isfinite(predicted)):
        return offset
    return offset + gain * (posterior.mean(axis=0) - predicted)


def pace_innovation(before: np.ndarray, after: np.ndarray, predicted: np.ndarray) -> float:
    """The images' mean correction of the particles' pace over one frame (log pace, see
    :func:`~tracker.core.representation.log_pace`): the log of :data:`PACE_FLOOR_MM` plus the mean ground step the
    resampled particles took, measured along the mean step the prior predicted for them, minus the log of
    :data:`PACE_FLOOR_MM` plus that predicted step's length. ``before``, ``after`` and ``predicted`` are ``P x 2``
    ground positions (mm) of the same particles: each root before the frame, after it (diffused, annealed and
    resampled), and where the prior put it before its ground diffusion (NaN before the first prediction: 0). The
    step taken is measured along the predicted one so that the posterior's sideways jitter (one view's depth) does
    not read as speed; a step taken backwards counts as standing still."""
    if not np.all(np.isfinite(predicted)):
        return 0.0
    expected = (predicted - before).mean(axis=0)
    taken = (after - before).mean(axis=0)
    length = float(np.hypot(*expected))
    along = float(taken @ expected) / length if length > 1e-9 else float(np.hypot(*taken))
    return float(np.log(PACE_FLOOR_MM + max(along, 0.0)) - np.log(PACE_FLOOR_MM + length))


class CRBMPrior(HeightOffsets, MotionPrior):
    """Samples every particle's next pose from its own history with a CRBM (one batch, torch).

    Given several models (e.g. orders 1, 3, 6) the highest order whose history is available is used, so
    higher orders start by "growing" the history with lower ones (Taylor 2009, Sec. 6.4). ``mode`` is
    ``'gibbs'`` (samples, for tracking) or ``'free-energy'`` (the best guess, for prediction).
    ``root_noise_mm`` adds ground-plane diffusion to each sample (see :data:`priors.common.ROOT_NOISE_MM`).
    The filter keeps ``order`` = the highest order poses per particle; the prior's own per-particle state is
    a dict of ``step`` ``P x 3``, the pending step (:data:`~tracker.core.representation.STEP_FEATURES`) of
    the newest history frame, which the previous sample chose; ``log_pace`` ``(P,)``, the log factor between
    the particle's ground steps and the model's (``pace_spread``/``pace_drift``, see
    :func:`priors.common.scale_ground_steps`); for models trained with a pace input instead ``pace`` ``(P,)``,
    the particle's own log pace (:func:`~tracker.core.representation.log_pace`), which the model is given and
    which starts at the known frames' pace with std ``pace_spread``, drifts by ``pace_drift`` per frame, is drawn
    afresh from the training paces with probability ``pace_jump`` per frame and never falls below standing
    still (``log_pace`` then stays 0); with ``relative_height``, ``height`` ``(P,)``, the known frames' mean root
    height (mm), by which the model's heights are shifted (see :func:`priors.common.shift_height`; a model trained
    with ``standing_height`` is shifted by the person's standing root height instead, ``standing_root_height``,
    and needs no state); with ``height_spread`` or ``height_drift``, ``height_offset`` ``(P,)``, the particle's own
    root-height offset (mm, the person's height minus the model's; :data:`priors.common.HEIGHT_SPREAD_OPTION`;
    ``height_spread=None``, the default, is :data:`PACED_HEIGHT_SPREAD` for a paced model and 0 otherwise),
    by which the model's heights are shifted as well; with ``posture_gain`` > 0 (``None``, the default, is
    :data:`PACED_POSTURE_GAIN` for a paced model and 0 otherwise), ``posture_offset`` ``(Kp,)`` (rad, shared
    by the particles; :func:`updated_posture_offset`) and ``posture_predicted`` ``(P, Kp)``, the posture
    angles the prior predicted for each particle; with ``pace_gain`` > 0, ``ground_predicted`` ``P x 2``, where
    the prior put each root before its ground diffusion (mm; :meth:`corrected_pace`); and ``walked`` ``(P,)``,
    whether its latest sample came from the robust option's random walk (``robust_fraction``, adapted to the
    posterior when ``robust_adaptive``, see :func:`priors.common.robust_share`). Each sample's torch generator is
    seeded from the filter's generator.
    """

    name = "crbm"
    #: Class defaults of the settings a subclass that bypasses ``__init__`` (the FCRBM prior) leaves off.
    paced: bool = False
    relative_height: bool = False
    pace_jump: float = 0.0
    #: The tracked person's standing root height (mm), above which a model trained with ``standing_height``
    #: predicts the root height; None for models of absolute heights.
    standing_root_height: float | None = None
    #: With a number (mm/frame per frame): each particle's ground step persists from frame to frame, changed by
    #: Gaussian noise of this std, instead of the model's predicted step (:func:`priors.common.persist_ground_step`).
    ground_velocity_noise: float | None = None
    #: The fraction of a particle's own ground velocity lost per frame (with ``ground_velocity_noise``).
    ground_velocity_pull: float = 0.0
    #: The fraction per frame of the likelihood's mean posture correction added to the posture offset the model's
    #: history and prediction are shifted by (:func:`updated_posture_offset`); 0: no offset. This class value is
    #: what a subclass that bypasses ``__init__`` (the FCRBM prior) keeps; ``__init__`` sets
    #: :data:`PACED_POSTURE_GAIN` for a paced model by default.
    posture_gain: float = 0.0
    #: The fraction per frame of the images' mean pace correction (:func:`pace_innovation`) added to every
    #: particle's pace (paced models only); 0: none.
    pace_gain: float = 0.0

    def __init__(self, models: Sequence[CRBMModel], gibbs_steps: int = GIBBS_STEPS,
                 device: str = "cpu", mode: str = "gibbs", root_noise_mm: float = ROOT_NOISE_MM,
                 robust_fraction: float = 0.0, heading_noise: float = 0.0, robust_adaptive: bool = False,
                 pace_spread: float | None = None, pace_drift: float | None = None, relative_height: bool = False,
                 pace_jump: float | None = None, standing_root_height: float | None = None,
                 ground_velocity_noise: float | None = None, ground_velocity_pull: float = 0.0,
                 height_spread: float | None = None, height_drift: float = 0.0, posture_gain: float | None = None,
                 pace_gain: float = 0.0):
        if not models:
            raise InputError("the CRBM prior needs at least one model")
        orders = [m.order for m in models]
        if len(set(orders)) < len(orders):  # one would silently replace the other
            raise InputError(f"the CRBM prior takes one model per order (the lower orders grow the history), got "
                             f"orders {', '.join(map(str, orders))}; several model files all of one order make an "
                             "ensemble")
        by_order = {m.order: m for m in models}
        for m in models:  # the lower orders a model file carries, unless given explicitly
            for g in m.growth:
                by_order.setdefault(g.order, g)
        self.models = [by_order[o] for o in sorted(by_order)]
        first = self.models[0]
        for m in self.models[1:]:
            if m.dof_names != first.dof_names or abs(m.fps - first.fps) > 1e-6 or m.body_model != first.body_model:
                raise InputError("CRBM models for one prior must share body model, pose layout and frame rate")
            if (m.pace_label is None) != (first.pace_label is None):
                raise InputError("CRBM models for one prior must all have a pace input or none")
            if m.standing_height != first.standing_height:
                raise InputError("CRBM models for one prior must all learn heights above standing or none")
        if first.standing_height:
            if relative_height:
                raise InputError("relative height is for models of absolute heights; this CRBM already predicts "
                                 "the height above the person's standing height")
            if standing_root_height is None or not standing_root_height > 0:
                raise InputError("this CRBM predicts the root height above the person's standing height and needs "
                                 f"it (the body model's rest root height, mm), got {standing_root_height}")
            self.standing_root_height = float(standing_root_height)
        self.paced = first.pace_label is not None
        pace_spread = self._paced_default(pace_spread, PACED_SPREAD)
        pace_drift = self._paced_default(pace_drift, PACED_DRIFT)
        pace_jump = self._paced_default(pace_jump, PACED_JUMP)
        if not 0.0 <= pace_jump <= 1.0:
            raise InputError(f"pace jump must be a probability in [0, 1], got {pace_jump}")
        if pace_jump > 0 and not self.paced:
            raise InputError("pace jump needs a CRBM trained with a pace input (train --pace-input); this one has none")
        self.pace_jump = float(pace_jump)
        if gibbs_steps < 1:
            raise InputError(f"Gibbs steps must be at least 1, got {gibbs_steps}")
        if mode not in ("gibbs", "free-energy"):
            raise InputError(f"CRBM prior mode must be 'gibbs' or 'free-energy', got {mode!r}")
        self.mode = mode
        if not root_noise_mm >= 0:
            raise InputError(f"root noise must be a non-negative number of mm, got {root_noise_mm}")
        self.root_noise_mm = float(root_noise_mm)
        if not 0.0 <= robust_fraction <= 1.0:
            raise InputError(f"robust fraction must lie in [0, 1], got {robust_fraction}")
        self.robust_fraction = float(robust_fraction)
        if not heading_noise >= 0:
            raise InputError(f"heading noise must be a non-negative number of radians, got {heading_noise}")
        self.heading_noise = float(heading_noise)
        self.robust_adaptive = bool(robust_adaptive)
        if not (pace_spread >= 0 and pace_drift >= 0):
            raise InputError(f"pace spread and drift must be non-negative (log units), got {pace_spread}, {pace_drift}")
        self.pace_spread, self.pace_drift = float(pace_spread), float(pace_drift)
        self.relative_height = bool(relative_height)
        self.ground_velocity_noise, self.ground_velocity_pull = checked_ground_velocity(
            ground_velocity_noise, ground_velocity_pull, pace_jump)
        self.set_height_offsets(self._paced_default(height_spread, PACED_HEIGHT_SPREAD), height_drift)
        self.posture_gain = checked_fraction_per_frame(
            "posture gain", self._paced_default(posture_gain, PACED_POSTURE_GAIN))
        pace_gain = checked_fraction_per_frame("pace gain", pace_gain)
        if pace_gain > 0 and not self.paced:
            raise InputError("pace gain corrects the pace a CRBM trained with a pace input is given (train "
                             "--pace-input); this one has none")
        if pace_gain > 0 and self.ground_velocity_noise is not None:
            raise InputError("pace gain corrects the pace of the model's own ground steps; with ground velocity noise "
                             "the pace is the particle's own ground speed")
        self.pace_gain = pace_gain
        if self.paced:
            self.summary_names, self.summary_kind = ("pace (mm/frame)",), "quantity"
        if self.height_offsets:
            self.summary_names, self.summary_kind = self.summary_names + ("height offset (mm)",), "quantity"
        if self.posture_gain > 0:
            self.summary_names, self.summary_kind = self.summary_names + ("posture offset rms (deg)",), "quantity"
        self.order = self.models[-1].order
        self.gibbs_steps = gibbs_steps
        self.device = torch.device(device)
        for m in self.models:
            m.crbm.W, m.crbm.A, m.crbm.B, m.crbm.a, m.crbm.b = (
                getattr(m.crbm, k).to(self.device) for k in CRBM.PARAMS)

    def _paced_default(self, value: float | None, paced_value: float) -> float:
        """``value``, or where it was left unset (None) the default of a setting that only a paced model uses:
        ``paced_value`` for a model trained with a pace input, 0 otherwise."""
        if value is not None:
            return value
        return paced_value if self.paced else 0.0

    def settings(self) -> dict:
        return {"orders": [m.order for m in self.models], "gibbs_steps": self.gibbs_steps,
                "root_noise_mm": self.root_noise_mm, "mode": self.mode, "robust_fraction": self.robust_fraction,
                "robust_adaptive": self.robust_adaptive, "heading_noise_rad": self.heading_noise,
                "pace_spread": self.pace_spread, "pace_drift": self.pace_drift,
                "relative_height": self.relative_height, "pace_jump": self.pace_jump,
                "standing_root_height_mm": self.standing_root_height,
                "ground_velocity_noise_mm": self.ground_velocity_noise,
                "ground_velocity_pull": self.ground_velocity_pull,
                "height_spread_mm": self.height_spread, "height_drift_mm": self.height_drift,
                "posture_gain": self.posture_gain, "pace_gain": self.pace_gain}

    def model_for(self, available: int) -> CRBMModel:
        """The highest-order model whose history is all real poses (never a padded history)."""
        usable = [m for m in self.models if m.order <= available]
        if not usable:
            raise InputError(f"the CRBM of order {self.models[0].order} needs {self.models[0].order} known "
                             f"frame(s), {available} given: give more known frames or a lower-order model to "
                             "grow from (train embeds one; or pass --model crbm1.pt crbmN.pt)")
        return usable[-1]

    def label_for(self, available: int) -> str:
        return f"crbm order {self.model_for(available).order}"

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        """The pending step of the last known frame (see :func:`~tracker.core.representation.pending_step`),
        each particle's log pace, and no random-walk samples yet. Refuses known frames too few for every model
        (a higher order never runs on a padded history)."""
        self.model_for(min(len(np.atleast_2d(known)), self.order))
        step = pending_step(known)
        state = {"step": np.repeat(step[None], n_particles, axis=0),
                 "log_pace": gaussian_start(n_particles, 0.0 if self.paced else self.pace_spread, rng),
                 "walked": np.zeros(n_particles, bool)}
        if self.paced:
            state["pace"] = np.maximum(log_pace(step) + gaussian_start(n_particles, self.pace_spread, rng),
                                       STANDING_LOG_PACE)
        if self.relative_height:
            state["height"] = np.full(n_particles, float(np.mean(np.atleast_2d(known)[:, 2])))
        if self.posture_gain > 0:  # no offset yet, and no prediction to measure the first correction against
            n_posture = len(posture_features(np.atleast_2d(known).shape[-1]))
            state["posture_offset"] = np.zeros((n_particles, n_posture))
            state["posture_predicted"] = np.full((n_particles, n_posture), np.nan)
        if self.pace_gain > 0:  # no prediction yet to measure the first pace correction against
            state["ground_predicted"] = np.full((n_particles, 2), np.nan)
        return {**state, **self.start_height_offsets(n_particles, rng)}

    def restart(self, state: PriorState, recent: np.ndarray, n_particles: int,
                rng: np.random.Generator) -> PriorState:
        """:meth:`start` from ``recent``, keeping the posture offset (it is the person's, not the lost frame's)."""
        new = self.start(recent, n_particles, rng)
        if self.posture_gain > 0:
            new["posture_offset"] = np.repeat(np.asarray(state["posture_offset"])[:1], n_particles, axis=0)
        return new

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        model = self.model_for(available)
        n = model.order
        step = list(STEP_FEATURES)
        feats = poses_to_invariant(history[:, -n - 1:] if history.shape[1] > n else
                                   np.concatenate([history[:, :1], history], axis=1))[:, -n:]
        feats[:, -1, step] = state["step"]
        previous = feats[:, -1].copy()  # the newest frame's features with the step the particle takes
        posture = posture_features(feats.shape[-1])
        offset = None
        if self.posture_gain > 0:  # the same for every particle: the rows are copies
            offset = updated_posture_offset(state["posture_offset"][0], previous[:, posture],
                                            state["posture_predicted"][0], self.posture_gain)
            feats[:, :, posture] -= offset  # the history in the postures the model knows
        if self.height_offsets:
            state = {**state, "height_offset": gaussian_drift(state["height_offset"], self.height_drift, rng)}
        to_model = self.height_to_model(model, state, len(feats))
        if to_model is not None:  # the history at the heights the model was trained on
            shift_height(feats, to_model)
        scale_ground_steps(feats, np.exp(-state["log_pace"]))  # the history at the model's pace
        z = model.normaliser.transform(feats).reshape(len(feats), -1)  # P x (n K)
        pace = None
        if self.paced:  # the model is told each particle's pace, which drifts (and may jump) first, or is the
            # speed of the ground step the particle takes now when that step is its own
            pace = (self.next_pace(model, self.corrected_pace(history, state), rng)
                    if self.ground_velocity_noise is None else np.maximum(log_pace(state["step"]), STANDING_LOG_PACE))
            z = np.concatenate([model.pace_input(pace), z], axis=1)
        hist = torch.tensor(z, dtype=torch.float32, device=self.device)
        generator = torch_generator(rng, self.device)
        if self.mode == "free-energy":  # the deterministic best guess (eq. 4.19)
            v = model.crbm.best_guess(hist)
        with torch.no_grad():
            if self.mode == "gibbs":
                v = model.crbm.gibbs(hist, self.gibbs_steps, generator)
        f_next = model.normaliser.inverse(v.cpu().double().numpy())
        if offset is not None:  # and the prediction in the person's
            f_next[:, posture] += offset
        step_factor = state["log_pace"] if self.paced else gaussian_drift(state["log_pace"], self.pace_drift, rng)
        scale_ground_steps(f_next, np.exp(step_factor))  # the predicted step at the particle's pace
        if to_model is not None:  # and the prediction at the person's
            shift_height(f_next, -to_model)
        poses = next_poses(history[:, -1], previous, f_next)
        predicted_ground = poses[:, :2].copy() if self.pace_gain > 0 else None  # before the ground diffusion
        add_ground_diffusion(poses, self.root_noise_mm, rng)
        add_heading_diffusion(poses, history[:, -1], self.heading_noise, rng)
        pending = f_next[:, step]
        if self.ground_velocity_noise is not None:  # the particle's own ground step persists, not the model's
            pending[:, :2] = persist_ground_step(state["step"], self.ground_velocity_noise, rng,
                                                  self.ground_velocity_pull)
        share = robust_share(state["walked"], self.robust_fraction, self.robust_adaptive)
        walked = mix_in_random_walk(poses, history[:, -1], model.pose_step_rms, share, rng)
        pending[walked] = steps_taken(history[walked, -1], poses[walked])
        new = {"step": pending, "log_pace": step_factor, "walked": walked}
        if pace is not None:
            new["pace"] = pace
        if self.relative_height:
            new["height"] = state["height"]
        if self.height_offsets:
            new["height_offset"] = state["height_offset"]
        if predicted_ground is not None:  # a random-walk sample's prediction is where it went
            predicted_ground[walked] = poses[walked, :2]
            new["ground_predicted"] = predicted_ground
        if offset is not None:
            new["posture_offset"] = np.repeat(offset[None], len(poses), axis=0)
            new["posture_predicted"] = np.repeat(f_next[:, posture].mean(axis=0)[None], len(poses), axis=0)
        return poses, new

    def height_to_model(self, model: CRBMModel, state: PriorState, n: int) -> np.ndarray | None:
        """The shift ``(n,)`` (mm) from the person's root heights to the heights ``model`` was trained on, or None
        when there is none: minus the person's standing root height for a model of heights above standing, the
        training frames' mean height minus the known frames' with ``relative_height``; less each particle's own
        height offset when it carries one."""
        shift = None
        if model.standing_height:
            shift = np.full(n, -self.standing_root_height)
        elif self.relative_height:
            shift = model.normaliser.mean[2] - state["height"]
        if self.height_offsets:
            shift = (0.0 if shift is None else shift) - state["height_offset"]
        return shift

    def corrected_pace(self, history: np.ndarray, state: PriorState) -> np.ndarray:
        """Each particle's log pace ``(P,)`` moved by :attr:`pace_gain` times the images' mean correction of the
        frame just tracked (:func:`pace_innovation`; the same move for every particle, so that the particles keep
        their spread of paces): an integrator that moves the paces the model is given until the steps it predicts
        are, on average, the steps the images select. Unchanged without a pace gain or a frame to measure."""
        if self.pace_gain == 0 or history.shape[1] < 2:
            return state["pace"]
        innovation = pace_innovation(history[:, -2, :2], history[:, -1, :2], state["ground_predicted"])
        return state["pace"] + self.pace_gain * innovation

    def next_pace(self, model: CRBMModel, pace: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Each particle's log pace ``(P,)`` one frame on: a random-walk step of ``pace_drift``, with probability
        ``pace_jump`` a fresh draw from the training frames' paces (Gaussian, ``model.pace_label``), never below
        standing still (:data:`~tracker.core.representation.STANDING_LOG_PACE`)."""
        pace = np.array(gaussian_drift(pace, self.pace_drift, rng), float)
        if self.pace_jump > 0:
            jump = rng.random(len(pace)) < self.pace_jump
            mean, std = model.pace_label
            pace[jump] = mean + std * rng.standard_normal(int(jump.sum()))
        return np.maximum(pace, STANDING_LOG_PACE)

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray | None:
        """The posterior means of :attr:`summary_names`: with a pace input the pace (mm/frame, ground speed), with
        height offsets the offset (mm); None with neither."""
        values = []
        if self.paced:
            values.append(float(np.sum(weights * (np.exp(state["pace"]) - PACE_FLOOR_MM))))
        if self.height_offsets:
            values.append(self.mean_height_offset(state, weights))
        if self.posture_gain > 0:
            values.append(float(np.degrees(np.sqrt(np.mean(np.asarray(state["posture_offset"])[0] ** 2)))))
        return np.array(values) if values else None

    def diffusion_std(self) -> np.ndarray:
        return self.models[-1].pose_step_rms


# ---------------------------------------------------------------------------
# Registration: building from model files, training from clips
# ---------------------------------------------------------------------------

def parse_history_noise(value: str | float) -> str | float:
    """The ``history_noise`` training option: 'auto', or a number of normalised units in [0, 100]; anything else
    is an :class:`InputError` saying so."""
    if value == "auto":
        return value
    try:
        noise = float(value)
    except (TypeError, ValueError):
        raise InputError(f"history noise must be 'auto' or a number, got {value!r}") from None
    if not 0 <= noise <= 100:
        raise InputError(f"history noise must lie in [0, 100] (normalised units), got {value!r}")
    return noise


def train_crbm_prior(data: TrainingData, options: dict, rng: np.random.Generator,
                     progress: Callable[[int, int, dict], None] | None = None,
                     checkpoint: Path | None = None, resume: bool = False) -> CRBMModel:
    """``train --prior crbm``: a CRBM of ``options['order']`` on the clips of ``data``."""
    noise = parse_history_noise(options["history_noise"])
    pace_input = options["pace_input"]
    if pace_input is None:  # auto: only clips of several paces can teach the model what a pace means
        pace_input = paces_vary(given_clips(data), data.fps)
    config = CRBMConfig(order=options["order"], hidden=options["hidden"], epochs=options["epochs"],
                        cd_k=options["cd_k"], batch_size=options["batch_size"], history_noise=noise,
                        sparsity_target=options["sparsity"], pace_input=pace_input,
                        standing_height=options["standing_height"], validation=options["validation"],
                        posture_offset=options["posture_offset"]).check()
    grow = _growth_orders(options["grow_from"], config.order)
    every = options["checkpoint_every"] or 0
    orders = grow + [config.order]
    total = config.epochs * len(orders)
    done: list[CRBMModel] = []
    state = None
    if resume:  # the growth models finished before, and the training state of the one in progress
        if checkpoint is None or not checkpoint.exists():
            raise InputError("no training checkpoint to resume from", checkpoint)
        doc = read_model_file(checkpoint, CHECKPOINT_FORMAT, "CRBM training checkpoint")
        saved = doc.get("config", {})
        if "training_state" not in doc or doc.get("stage_orders") != orders \
                or any(bool(saved.get(key, False)) != getattr(config, key) for key in INPUT_SETTINGS):
            raise InputError("the checkpoint is not of this training (other orders, another "
                             f"{' or '.join(INPUT_SETTINGS.values())}, or a finished model)", checkpoint)
        done = [_model_from_document(g, checkpoint, "cpu") for g in doc["growth"]]
        state = doc["training_state"]
        for _ in done:  # the draws the finished stages took from rng
            rng.integers(2 ** 62)

    def save(stage_model: CRBMModel, training_state: dict) -> None:
        from copy import copy

        snapshot = copy(stage_model)
        snapshot.growth = list(done)
        doc = {**snapshot.to_document(), "format": CHECKPOINT_FORMAT, "training_state": training_state,
               "stage_orders": orders}
        torch_save_atomic(doc, checkpoint)  # a model is never half-written: the rename is atomic

    for i in range(len(done), len(orders)):  # the lower orders first, on the same clips, each with its own draws
        report = None if progress is None else (
            lambda epoch, err, before=i * config.epochs: progress(before + epoch, total, {"reconstruction": err}))
        model = train_crbm(list(data.clips), replace(config, order=orders[i]), data.fps,
                           data.body_model.dof_names, data.body_model.name, list(data.sources), report,
                           (save, every) if checkpoint is not None and every else None, rng=rng,
                           resume=state if i == len(done) else None,
                           standing_heights=data.standing_heights or None)
        if i < len(grow):
            done.append(model)
    model.growth = done
    for m in [model, *done]:
        m.time_warp = list(data.time_warp)
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
    return model


def _growth_orders(text: str, order: int) -> list[int]:
    """The lower orders named by ``grow_from`` ("1", "1,3" or "none") that are below ``order``."""
    if str(text).strip().lower() == "none":
        return []
    try:
        orders = sorted({int(t) for t in str(text).split(",") if t.strip()})
    except ValueError:
        raise InputError(f"grow_from must be 'none' or comma-separated orders like '1,3', got {text!r}") from None
    if any(o < 1 for o in orders):
        raise InputError(f"grow_from orders must be at least 1, got {text!r}")
    return [o for o in orders if o < order]


CRBM_TRAIN_OPTIONS = (
    Option("order", int, CRBMConfig.order, "CRBM order N (default 3)", minimum=1, maximum=100),
    Option("hidden", int, CRBMConfig.hidden, "hidden units (default 150)", minimum=1, maximum=100000),
    Option("epochs", int, CRBMConfig.epochs, "passes through the data (default 500)", minimum=1,
           maximum=1000000),
    Option("cd_k", int, CRBMConfig.cd_k, "Gibbs steps of contrastive divergence (default 10)", minimum=1,
           maximum=10000),
    Option("batch_size", int, CRBMConfig.batch_size, "windows per mini-batch (default 100)", minimum=1,
           maximum=1000000),
    Option("history_noise", str, "auto",
           "std of the noise added to the history in training (normalised units), or 'auto' (default)"),
    Option("sparsity", float, None, "target mean activation of the hidden units (default: no sparsity term)"),
    Option("checkpoint_every", int, None, "also save the model every this many epochs", minimum=1),
    Option("grow_from", str, "1", "lower orders trained alongside and saved in the same file, which grow the "
                                  "history from the known frames (Taylor 2009, Sec. 6.4); 'none' to skip (default 1)"),
    Option("pace_input", bool, None, "condition the model on each frame's pace (log ground speed averaged over one "
                                     "second), which each particle carries while tracking (default: on when the "
                                     f"clips' paces vary, std of log pace >= {PACE_SPREAD_FOR_INPUT:g}, e.g. the "
                                     "walks of several people; --no-pace-input to turn it off)"),
    Option("validation", float, CRBMConfig.validation,
           "fraction of each clip (its last frames) held out to choose the epoch: the weights of the epoch with the "
           "least held-out one-step error, checked every 10 epochs, are kept (default 0: the last epoch's)",
           minimum=0.0, maximum=0.5),
    Option("standing_height", bool, False, "learn the root height above each subject's standing root height "
                                           "(its body model's) instead of above the floor, and track it above the "
                                           "person's own, so that one model fits people of other sizes (default "
                                           "off: it won issue 13's tuning folds but lost its one-view test folds)"),
    Option("posture_offset", float, CRBMConfig.posture_offset,
           "std in rad of a random constant added to every posture angle (root pitch and roll, joint angles) of "
           "each training window, history and predicted frame alike, so that the model keeps an unseen person's "
           "posture instead of pulling it toward its training subjects' (default 0: off)", minimum=0.0,
           maximum=float(math.pi)),
)


POSTURE_GAIN_HELP = ("fraction per frame of the images' mean posture correction (posterior minus predicted mean "
                     "posture angles) added to an offset by which the model's history and prediction are shifted, so "
                     "that it stops pulling an unseen person's posture toward its training subjects'")
#: ``track --posture-gain`` (the deep CRBM's; the CRBM's default depends on its pace input):
#: :attr:`CRBMPrior.posture_gain`.
POSTURE_GAIN_OPTION = Option("posture_gain", float, 0.0, f"{POSTURE_GAIN_HELP} (default 0: off)", minimum=0.0,
                             maximum=1.0)


def _paced_default_option(option: Option, help_text: str, paced_value: float) -> Option:
    """``option`` left unset by default (None, resolved by :meth:`CRBMPrior._paced_default`), its help saying so."""
    return replace(option, default=None,
                   help=f"{help_text} (default {paced_value:g} for a CRBM trained with a pace input, 0 otherwise)")


@register_prior(
    "crbm", summary="Conditional RBM (Taylor 2009); several model files of increasing order grow the history, "
                    "several of one order form an ensemble",
    model_files="several", train=train_crbm_prior, train_options=CRBM_TRAIN_OPTIONS, resumable=True,
    options=(gibbs_steps_option(GIBBS_STEPS),
             ROOT_NOISE_OPTION,
             *UNLEARNED_MOTION_OPTIONS,
             HEADING_NOISE_OPTION,
             Option("pace_jump", float, None, "probability per frame that a particle's pace is drawn afresh from "
                                              f"the training paces (CRBMs trained with a pace input; default "
                                              f"{PACED_JUMP:g})", minimum=0.0, maximum=1.0),
             GROUND_VELOCITY_OPTION,
             GROUND_VELOCITY_PULL_OPTION,
             _paced_default_option(HEIGHT_SPREAD_OPTION, HEIGHT_SPREAD_HELP, PACED_HEIGHT_SPREAD),
             HEIGHT_DRIFT_OPTION,
             _paced_default_option(POSTURE_GAIN_OPTION, POSTURE_GAIN_HELP, PACED_POSTURE_GAIN),
             Option("pace_gain", float, 0.0, "fraction per frame of the images' mean pace correction (log of the "
                                             "ground step the resampled particles took over the one the prior "
                                             "predicted for them) added to every particle's pace, so that the pace "
                                             "follows a person who speeds up or slows down (CRBMs trained with a "
                                             "pace input; default 0: off)", minimum=0.0, maximum=1.0),
             Option("relative_height", bool, False, "keep the person's own root height, the model's heights moved "
                                                    "by the known frames' mean root height minus the training "
                                                    "frames' (default off; for models of absolute heights, not "
                                                    "those trained with --standing-height)")))
def build_crbm(context: PriorContext, model_files: Sequence[Path], options: dict) -> CRBMPrior | EnsemblePrior:
    """The CRBM prior of ``model_files``: models of increasing order grow the history; several files all of one
    order (each with the growth models it carries) form an ensemble, each drawing its share of the particles
    (:class:`priors.ensemble.EnsemblePrior`)."""
    models = [load_crbm(m, device=context.device) for m in model_files]
    for path, m in zip(model_files, models):
        m.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps, path)

    def prior(of: list[CRBMModel]) -> CRBMPrior:
        return CRBMPrior(of, gibbs_steps=options["gibbs_steps"], root_noise_mm=options["root_noise"],
                         device=context.device, robust_fraction=options["robust_fraction"],
                         heading_noise=options["heading_noise"], robust_adaptive=options["robust_adaptive"],
                         pace_spread=options["pace_spread"], pace_drift=options["pace_drift"],
                         relative_height=options["relative_height"], pace_jump=options["pace_jump"],
                         standing_root_height=context.body_model.rest_root_height,
                         ground_velocity_noise=options["ground_velocity_noise"],
                         ground_velocity_pull=options["ground_velocity_pull"],
                         height_spread=options["height_spread"], height_drift=options["height_drift"],
                         posture_gain=options["posture_gain"], pace_gain=options["pace_gain"])

    if len(models) > 1 and len({m.order for m in models}) == 1:
        return EnsemblePrior([prior([m]) for m in models])
    return prior(models)
