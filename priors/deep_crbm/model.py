"""Two-layer CRBM motion prior: a Conditional Deep Belief Network (Taylor 2009, Sec. 4.3), in torch.

Training is greedy. The first layer is the CRBM of :mod:`priors.crbm.model` (order ``N``, Gaussian visible units on the
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

Training is :mod:`priors.deep_crbm.training`, the model file :mod:`priors.deep_crbm.file`, the tracking prior
:mod:`priors.deep_crbm.prior`.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from priors.common import torch_save_atomic
from priors.crbm.model import CRBM, CRBMModel, bernoulli_
from priors.settings import TopConfig

FORMAT = "pose-tracker deep-crbm v1"
#: The format of a training checkpoint saved while the second layer trains (while the first trains, the CRBM's).
CHECKPOINT_FORMAT = "pose-tracker deep-crbm training checkpoint v1"


def deep_gibbs(bottom: CRBM, top: CRBM, history: torch.Tensor, steps: int, generator: torch.Generator | None
               ) -> torch.Tensor:
    """Next frames ``B x K`` from histories ``B x ((N + M) K)`` (oldest first) by the up-pass, the second layer's
    Gibbs sampling and the down-pass of the module docstring."""
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


@dataclass
class DeepCRBMModel:
    """The first layer (a :class:`priors.crbm.model.CRBMModel`, with the lower orders it grows from) and the second."""
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


