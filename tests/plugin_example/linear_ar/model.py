"""The linear autoregressive model: the next frame's normalised invariant features ``x_t`` (``K``) are
``A x_{t-1} + b`` plus Gaussian noise of standard deviation ``noise`` per feature."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch

from priors.common import TrainedModel

FORMAT = "linear-ar-model-1"  # the model files' format entry


@dataclass(kw_only=True)
class LinearARModel(TrainedModel):
    """``A`` ``K x K``, ``b`` ``(K,)`` and ``noise`` ``(K,)``, in the normaliser's units (standard deviations of
    the training features), plus what every learned prior's model keeps (:class:`priors.common.ModelData`)."""

    A: np.ndarray
    b: np.ndarray
    noise: np.ndarray
    order: ClassVar[int] = 1  # one history frame: the prior draws from the first known frame on
    KIND: ClassVar[str] = "linear autoregressive"

    def to_document(self) -> dict:
        """The model file's dictionary (:meth:`~priors.common.TrainedModel.save` writes it)."""
        weights = {k: torch.tensor(getattr(self, k), dtype=torch.float64) for k in ("A", "b", "noise")}
        return {"format": FORMAT, **weights, **self.data_document()}

    def summary(self) -> str:
        """One line on the fit: the RMS one-step residual, in the normaliser's units."""
        return f"{self.KIND}: {len(self.b)} features, one-step residual {float(np.sqrt(np.mean(self.noise ** 2))):.3f}"
