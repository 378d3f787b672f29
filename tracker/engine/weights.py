"""Particle weights in the log domain: one small immutable object that derives normalised weights and the ESS."""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True)
class LogWeights:
    """Unnormalised log-weights ``(P,)``; ``-inf`` marks a particle with no weight.

    ``normalised`` (``W``, summing to 1) and ``ess`` are derived on first use.
    Arithmetic returns new objects, so a frame's record can keep the weights it saw.
    """

    log_w: np.ndarray

    def __post_init__(self) -> None:  # a NaN log-weight (a broken likelihood value) is a particle with no weight
        log_w = np.asarray(self.log_w, float)
        object.__setattr__(self, "log_w", np.where(np.isnan(log_w), -np.inf, log_w))

    @classmethod
    def uniform(cls, n_particles: int) -> "LogWeights":
        return cls(np.zeros(n_particles))

    def __len__(self) -> int:
        return len(self.log_w)

    def add(self, log_likelihood: np.ndarray) -> "LogWeights":
        """Weights after multiplying by a likelihood ``(P,)`` given in the log domain."""
        return LogWeights(self.log_w + log_likelihood)

    @property
    def any_finite(self) -> bool:
        """False when every particle has weight zero (every log-weight ``-inf`` or NaN)."""
        return bool(np.isfinite(np.max(self.log_w)))

    @cached_property
    def normalised(self) -> np.ndarray:
        """Weights ``(P,)`` summing to 1 (logsumexp-stable); raises if no particle has any weight."""
        top = np.max(self.log_w)
        if not np.isfinite(top):
            raise ValueError("every log-weight is -inf (or NaN): no particle explains the observation")
        w = np.exp(self.log_w - top)
        return w / w.sum()

    @property
    def ess(self) -> float:
        """Effective sample size ``1 / sum(W^2)``: P for uniform weights, 1 when one particle has it all."""
        return effective_sample_size(self.normalised)

    def renormalised(self) -> "LogWeights":
        """The same weights as ``log W`` (carried to the next frame when it does not resample)."""
        with np.errstate(divide="ignore"):
            return LogWeights(np.log(self.normalised))


def effective_sample_size(w: np.ndarray) -> float:
    """``1 / sum(w^2)`` for normalised weights ``(P,)``."""
    return float(1.0 / np.sum(w * w))
