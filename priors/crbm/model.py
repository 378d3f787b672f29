"""The Conditional Restricted Boltzmann Machine (Taylor 2009, Ch. 4), in torch, and a trained CRBM as saved in its
model file.

Model (Gaussian visible units with unit variance on normalised data, binary
hidden units, order N)::

    a_hat = a + A^T v_<t          b_hat = b + B^T v_<t          (eqs. 4.4, 4.7)
    p(h_j = 1 | v_t, v_<t) = sigmoid(b_hat_j + sum_i W_ij v_i,t)  (eq. 4.5)
    p(v_t | h_t, v_<t) = N(a_hat + W h_t, I)                      (eq. 4.6)
    F(v_t | v_<t) = 1/2 |v_t - a_hat|^2 - sum_j softplus(W_j^T v_t + b_hat_j)   (eq. 4.18)

``v_<t`` is the history, the N previous frames concatenated oldest first
(``N*K`` numbers for K features), after an optional context (the pace). Data are the invariant features of
:mod:`tracker.core.representation`, normalised by a :class:`FeatureNormaliser`
(constant dimensions dropped).

Generation (Sec. 4.2.3): alternating Gibbs sampling from ``v = v_{t-1}``, with
binary hidden samples, expected visible values and hidden probabilities on the
final step. "Best guess" prediction descends the free energy (eq. 4.19).

Training is :mod:`priors.crbm.training`, reading a model file :mod:`priors.crbm.file`, the tracking prior
:mod:`priors.crbm.prior`.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import ClassVar

import numpy as np
import torch

from priors.common import TrainedModel
from priors.settings import CRBMConfig
from tracker.core.representation import PACE_FLOOR_MM

FORMAT = "pose-tracker crbm v1"
#: Training checkpoints have their own format, so a half-trained model is never taken for a model file.
CHECKPOINT_FORMAT = "pose-tracker crbm training checkpoint v1"




#: The training settings that change what a model's inputs mean (name: what it is, for messages): the growth
#: models in a file and a resumed training must agree with the model on them.
INPUT_SETTINGS = {"pace_input": "pace input"}


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
        if self.best_epoch:
            best = min(e for _, e in self.validation_errors)
            fit += f"held-out one-step error {best:.4f} at epoch {self.best_epoch} (kept), "
        return (f"CRBM order {self.order}{grow}, {self.crbm.n_hidden} hidden units{pace}: "
                f"{fit}{self.training_seconds:.1f} s")

    def to_document(self) -> dict:
        """The model file's dictionary (tensors and plain values; ``torch.load(weights_only=True)`` reads it)."""
        config = asdict(self.config)
        # Settings at their defaults are left out, as in files written before they existed (readable by those).
        for key in ("validation", "validation_every"):
            if config[key] == getattr(CRBMConfig, key):
                del config[key]
        return {
            "format": FORMAT, "params": self.crbm.state_dict(), "config": config, **self.data_document(),
            "validation_errors": [[float(e), float(x)] for e, x in self.validation_errors],
            "best_epoch": int(self.best_epoch), "growth": [g.to_document() for g in self.growth],
            "pace_label": None if self.pace_label is None else [float(x) for x in self.pace_label],
        }

