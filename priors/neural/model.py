"""The neural prior's network, a mixture density network (Bishop 1994) over an MLP encoding of the history, and
a trained one as saved in its model file.

Model (normalised invariant features of :mod:`tracker.core.representation`, ``K`` per frame; ``N`` the order)::

    x   = [context, 0 .. 0, v_{t-n} .. v_{t-1}, mask]       (history of n <= N frames, left-padded to N; mask: which
                                                            of the N slots are real)
    h   = MLP(x)                                           (``layers`` SiLU layers of ``hidden`` units)
    p(v_t | history) = sum_m pi_m(h) N(v_t; v_{t-1} + mu_m(h), diag(sigma_m(h)^2))

so one network draws from any history length from one frame (the tracker's first step) to ``N``. Sampling draws
the component from ``pi`` and computes only that component's mean and scale, grouped by component, so its cost
per particle is the encoder's plus one component's heads.

Training is :mod:`priors.neural.training`, reading a model file :mod:`priors.neural.file`, the tracking prior
:mod:`priors.neural.prior`.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import ClassVar

import numpy as np
import torch

from priors.common import TrainedModel
from priors.neural.settings import NeuralConfig
from tracker.core.representation import PACE_FLOOR_MM

FORMAT = "pose-tracker neural v1"
#: Training checkpoints have their own format, so a half-trained model is never taken for a model file.
CHECKPOINT_FORMAT = "pose-tracker neural training checkpoint v1"
#: Bounds of each component's log scale (normalised units): e^-7 to e^2.
LOG_SCALE_RANGE = (-7.0, 2.0)


class MDN(torch.nn.Module):
    """The network: ``n_features`` (K) features per frame, up to ``order`` (N) history frames, ``n_context`` (C)
    inputs before the history (the pace), ``hidden`` units in each of ``layers`` layers, ``components`` (M)
    Gaussians. Conditioning inputs are ``B x (C + n K)`` for any ``n`` in 1 .. N (oldest frame first)."""

    def __init__(self, n_features: int, order: int, hidden: int, layers: int, components: int, n_context: int = 0):
        super().__init__()
        self.n_features, self.order, self.n_context, self.components = n_features, order, n_context, components
        sizes = [n_context + order * n_features + order] + [hidden] * layers
        blocks: list[torch.nn.Module] = []
        for a, b in zip(sizes[:-1], sizes[1:]):
            blocks += [torch.nn.Linear(a, b), torch.nn.SiLU()]
        self.encoder = torch.nn.Sequential(*blocks)
        self.logits = torch.nn.Linear(hidden, components)
        self.means = torch.nn.Linear(hidden, components * n_features)
        self.log_scales = torch.nn.Linear(hidden, components * n_features)
        with torch.no_grad():  # start near "the next frame is the last one, give or take one unit"
            self.means.weight.mul_(0.1)
            self.means.bias.zero_()
            self.log_scales.weight.mul_(0.1)
            self.log_scales.bias.fill_(-1.0)

    def frames_in(self, conditioning: torch.Tensor) -> int:
        """How many history frames ``conditioning`` ``B x (C + n K)`` holds (``n``), checked to be 1 .. N."""
        C, K = self.n_context, self.n_features
        n, rest = divmod(conditioning.shape[1] - C, K)
        if rest or not 1 <= n <= self.order:
            raise ValueError(f"conditioning of width {conditioning.shape[1]} is not {C} context inputs and 1 to "
                             f"{self.order} frames of {K} features")
        return n

    def encode(self, conditioning: torch.Tensor, lengths: torch.Tensor | None = None
               ) -> tuple[torch.Tensor, torch.Tensor]:
        """The encoding ``B x H`` and the last history frame ``B x K`` of ``conditioning`` ``B x (C + n K)``.
        ``lengths`` ``(B,)`` (training) cuts each row's history to its last ``lengths[b]`` frames of the n."""
        C, K, N = self.n_context, self.n_features, self.order
        B = conditioning.shape[0]
        n = self.frames_in(conditioning)
        history = conditioning[:, C:].reshape(B, n, K)
        slots = torch.arange(N - n, N, device=conditioning.device)  # the slots these frames fill
        if lengths is None:
            real = torch.ones(B, n, dtype=conditioning.dtype, device=conditioning.device)
        else:
            real = (slots[None] >= N - lengths[:, None]).to(conditioning.dtype)
            history = history * real[..., None]
        padded = conditioning.new_zeros(B, N - n, K)
        mask = torch.cat([conditioning.new_zeros(B, N - n), real], dim=1)
        x = torch.cat([conditioning[:, :C], padded.reshape(B, -1), history.reshape(B, -1), mask], dim=1)
        return self.encoder(x), history[:, -1]

    def mixture(self, conditioning: torch.Tensor, lengths: torch.Tensor | None = None
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Every component's log weight ``B x M``, mean ``B x M x K`` and log scale ``B x M x K``."""
        h, last = self.encode(conditioning, lengths)
        B, M, K = h.shape[0], self.components, self.n_features
        log_pi = torch.log_softmax(self.logits(h), dim=-1)
        mu = last[:, None] + self.means(h).view(B, M, K)
        log_s = self.log_scales(h).view(B, M, K).clamp(*LOG_SCALE_RANGE)
        return log_pi, mu, log_s

    def log_prob(self, v: torch.Tensor, conditioning: torch.Tensor, lengths: torch.Tensor | None = None
                 ) -> torch.Tensor:
        """Log density ``(B,)`` of the frames ``v`` ``B x K`` given the histories (normalised units)."""
        log_pi, mu, log_s = self.mixture(conditioning, lengths)
        z = (v[:, None] - mu) * torch.exp(-log_s)
        per = -0.5 * (z * z).sum(-1) - log_s.sum(-1) - 0.5 * self.n_features * math.log(2 * math.pi)
        return torch.logsumexp(log_pi + per, dim=-1)

    @torch.no_grad()
    def sample(self, conditioning: torch.Tensor, generator: torch.Generator | None,
               mean_only: bool = False) -> torch.Tensor:
        """Next frames ``B x K`` drawn for the histories ``conditioning``: one uniform per row picks the
        component, then ``K`` standard normals per row scale it (row ``b``'s numbers are row ``b``'s of the
        batch's draws). With ``mean_only`` the mean of the likeliest component, drawing nothing."""
        h, last = self.encode(conditioning)
        B, M, K = h.shape[0], self.components, self.n_features
        logits = self.logits(h)
        if mean_only:
            chosen = logits.argmax(dim=1)
            eps = None
        else:
            u = torch.rand(B, 1, generator=generator, device=h.device, dtype=h.dtype)
            cdf = torch.softmax(logits, dim=1).cumsum_(dim=1)
            chosen = (cdf < u * cdf[:, -1:]).sum(dim=1).clamp_(max=M - 1)
            eps = torch.randn(B, K, generator=generator, device=h.device, dtype=h.dtype)
        out = torch.empty(B, K, device=h.device, dtype=h.dtype)
        wm, bm = self.means.weight.view(M, K, -1), self.means.bias.view(M, K)
        ws, bs = self.log_scales.weight.view(M, K, -1), self.log_scales.bias.view(M, K)
        order = torch.argsort(chosen, stable=True)
        counts = torch.bincount(chosen, minlength=M).tolist()
        start = 0
        for m, count in enumerate(counts):  # the particles of each component together: one product each
            if not count:
                continue
            rows = order[start:start + count]
            start += count
            hm = h[rows]
            drawn = last[rows] + torch.addmm(bm[m], hm, wm[m].T)
            if eps is not None:
                scale = torch.addmm(bs[m], hm, ws[m].T).clamp_(*LOG_SCALE_RANGE).exp_()
                drawn.addcmul_(scale, eps[rows])
            out[rows] = drawn
        return out


@dataclass(kw_only=True)
class NeuralModel(TrainedModel):
    """A trained neural prior: its network and settings, and what :class:`~priors.common.TrainedModel` keeps.
    ``reconstruction_errors`` holds each epoch's mean training negative log-likelihood per frame (normalised
    units)."""

    net: MDN
    config: NeuralConfig
    #: With ``config.pace_input``: the mean and std of the training frames' log pace (None otherwise).
    pace_label: tuple[float, float] | None = None
    #: ``[epoch, held-out negative log-likelihood per frame]`` of every epoch (with ``config.validation``), and the
    #: epoch whose weights the model kept (0: the last).
    validation_errors: list[list[float]] = field(default_factory=list)
    best_epoch: int = 0

    KIND: ClassVar[str] = "neural prior"

    @property
    def order(self) -> int:
        return self.net.order

    def pace_input(self, log_paces: np.ndarray) -> np.ndarray:
        """The normalised pace input ``(P, 1)`` for log paces ``(P,)``."""
        mean, std = self.pace_label
        return ((np.asarray(log_paces, float) - mean) / std)[:, None]

    def summary(self) -> str:
        """One line on how training went."""
        errs = self.reconstruction_errors
        fit = f"training NLL {errs[0]:.2f} (epoch 1) -> {errs[-1]:.2f} (epoch {len(errs)}), " if errs else ""
        held = ""
        if self.best_epoch:
            best = min(e for _, e in self.validation_errors)
            held = f"held-out NLL {best:.2f} at epoch {self.best_epoch} (kept), "
        pace = "" if self.pace_label is None else \
            f", paced (training paces {np.exp(self.pace_label[0]) - PACE_FLOOR_MM:.1f} mm/frame typical)"
        c = self.config
        return (f"neural prior (MDN of {c.components} components, {c.layers}x{c.hidden} encoder) of order "
                f"{self.order} on {len(self.sources)} clip(s){pace}: {fit}{held}{self.training_seconds:.0f} s")

    def to_document(self) -> dict:
        """The model file's dictionary (:func:`priors.neural.file.load_neural` reads it back)."""
        return {"format": FORMAT, "config": asdict(self.config),
                "params": {k: v.detach().cpu().clone() for k, v in self.net.state_dict().items()},
                **self.data_document(),
                "pace_label": None if self.pace_label is None else [float(x) for x in self.pace_label],
                "validation_errors": [[float(e), float(x)] for e, x in self.validation_errors],
                "best_epoch": int(self.best_epoch)}


def build_net(config: NeuralConfig, n_features: int, n_context: int) -> MDN:
    """The untrained network of ``config`` (its initial weights from torch's global generator: seed it first)."""
    return MDN(n_features, config.order, config.hidden, config.layers, config.components, n_context)
