"""Sequential importance resampling with an N-order augmented state, optionally annealed.

Each frame (Taylor 2009, Sec. 6.3; DESIGN.md "Particle filter"):

1. every particle draws its next pose from the prior given its own last N
   poses (and the prior's own per-particle state);
2. its log-weight gains the frame's log-likelihood (weights are carried over
   frames that did not resample);
3. the estimate is the weighted mean pose (and the best particle is kept);
4. when the effective sample size falls below ``ess_threshold * P`` the
   particles are resampled (systematic by default) and the histories and prior
   state are reindexed together.

Annealing (Deutscher & Reid 2005) is an option of the same filter: with
``L > 1`` layers each frame reweights by ``beta_m * log-likelihood``, ``beta_m``
chosen by bisection so that the effective sample size is ``survival_rate * P``,
resamples, and diffuses with the prior's one-step scale times
``layer_diffusion_decay^m``; the last layer's weights are the frame's weights
and every frame ends with resampling.

If every weight is ``-inf`` (no particle explains the frame) the filter
records the frame, re-diffuses the particles around the last estimate, and
goes on; it never produces NaN. Every random draw comes from the one
generator passed in.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Iterable

import numpy as np

from tracker.engine.prior import MotionPrior
from tracker.engine.resampling import SCHEMES, effective_sample_size, normalise_log_weights


@dataclass(frozen=True)
class FilterSettings:
    n_particles: int = 1000
    resampling: str = "systematic"
    ess_threshold: float = 0.5
    annealing_layers: int = 1
    survival_rate: float = 0.5
    layer_diffusion_decay: float = 0.5

    def check(self) -> "FilterSettings":
        if self.n_particles < 1:
            raise ValueError(f"need at least one particle, got {self.n_particles}")
        if self.resampling not in SCHEMES:
            raise ValueError(f"unknown resampling scheme {self.resampling!r}; choose from {', '.join(SCHEMES)}")
        if not 0.0 <= self.ess_threshold <= 1.0:
            raise ValueError(f"ess_threshold must lie in [0, 1], got {self.ess_threshold}")
        if self.annealing_layers < 1:
            raise ValueError(f"annealing layers must be at least 1, got {self.annealing_layers}")
        if not 0.0 < self.survival_rate < 1.0:
            raise ValueError(f"survival rate must lie in (0, 1), got {self.survival_rate}")
        return self


@dataclass
class FilterResult:
    """Per tracked frame: ``mean_poses`` and ``best_poses`` ``T x D``, ``ess`` ``(T,)`` (before resampling),
    ``seconds`` ``(T,)`` (prior + likelihood + resampling), ``resampled`` ``(T,)`` bool; ``recovered`` lists
    the tracked-frame indices where every weight was -inf."""

    mean_poses: np.ndarray
    best_poses: np.ndarray
    ess: np.ndarray
    seconds: np.ndarray
    resampled: np.ndarray
    recovered: list[int] = field(default_factory=list)


def choose_beta(log_lik: np.ndarray, survival_rate: float, iterations: int = 40) -> float:
    """The exponent ``beta`` with ``ESS(exp(beta * log_lik)) ~= survival_rate * P`` (bisection on log beta)."""
    finite = np.isfinite(log_lik)
    if finite.sum() <= 1:
        return 1.0
    ll = log_lik[finite] - log_lik[finite].max()
    P = len(log_lik)

    def ess(beta: float) -> float:
        w = np.exp(beta * ll)
        w /= w.sum()
        return effective_sample_size(w)

    lo, hi = -12.0, 12.0  # log beta
    if ess(np.exp(hi)) >= survival_rate * P:
        return float(np.exp(hi))
    if ess(np.exp(lo)) <= survival_rate * P:
        return float(np.exp(lo))
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if ess(np.exp(mid)) > survival_rate * P:
            lo = mid
        else:
            hi = mid
    return float(np.exp(0.5 * (lo + hi)))


class ParticleFilter:
    """SIR over poses with the prior's order as the augmented-state length."""

    def __init__(self, prior: MotionPrior, settings: FilterSettings, rng: np.random.Generator):
        self.prior = prior
        self.settings = settings.check()
        self.rng = rng
        self.resample = SCHEMES[settings.resampling]

    def run(self, known: np.ndarray, frame_log_likelihoods: Iterable[Callable[[np.ndarray], np.ndarray]],
            on_frame: Callable[[int, np.ndarray], None] | None = None) -> FilterResult:
        """Track from the known poses ``n0 x D`` through one log-likelihood function per frame.

        Each function maps poses ``P x D`` to log-likelihoods ``(P,)``.
        ``on_frame(k, mean_pose)`` is called after every tracked frame.
        """
        s = self.settings
        known = np.atleast_2d(np.asarray(known, float))
        P, D, N = s.n_particles, known.shape[1], self.prior.order
        hist_known = known[-N:]
        if len(hist_known) < N:  # pad the oldest slots with the earliest known pose
            hist_known = np.concatenate([np.repeat(hist_known[:1], N - len(hist_known), axis=0), hist_known])
        history = np.repeat(hist_known[None], P, axis=0)  # P x N x D
        estimate_history = hist_known.copy()
        available = min(len(known), N)
        state = self.prior.start(known, P, self.rng)
        log_w = np.zeros(P)
        means, bests, esss, secs, resampled, recovered = [], [], [], [], [], []
        diffusion = self.prior.diffusion_std()
        for k, log_lik in enumerate(frame_log_likelihoods):
            t0 = time.perf_counter()
            x, state = self.prior.sample(history, available, state, self.rng)
            ll = log_lik(x)
            if s.annealing_layers > 1:
                for m in range(s.annealing_layers - 1):
                    if not np.any(np.isfinite(ll)):
                        break
                    w = normalise_log_weights(choose_beta(ll, s.survival_rate) * ll)
                    idx = self.resample(w, self.rng)
                    x, history, ll = x[idx], history[idx], ll[idx]
                    state = self.prior.reindex(state, idx)
                    x = x + self.rng.standard_normal(x.shape) * diffusion * s.layer_diffusion_decay ** (m + 1)
                    ll = log_lik(x)
                frame_log_w = choose_beta(ll, s.survival_rate) * ll
            else:
                frame_log_w = log_w + ll
            if not np.any(np.isfinite(frame_log_w)):
                recovered.append(k)
                x = estimate_history[-1] + self.rng.standard_normal((P, D)) * diffusion
                history = np.repeat(estimate_history[None], P, axis=0)
                ll = log_lik(x)
                frame_log_w = ll if np.any(np.isfinite(ll)) else np.zeros(P)
            w = normalise_log_weights(frame_log_w)
            mean = w @ x
            means.append(mean)
            bests.append(x[int(np.argmax(w))])
            ess = effective_sample_size(w)
            esss.append(ess)
            history = np.concatenate([history[:, 1:], x[:, None]], axis=1)
            estimate_history = np.concatenate([estimate_history[1:], mean[None]])
            available = min(available + 1, N)
            do_resample = s.annealing_layers > 1 or ess < s.ess_threshold * P
            if do_resample:
                idx = self.resample(w, self.rng)
                history = history[idx]
                state = self.prior.reindex(state, idx)
                log_w = np.zeros(P)
            else:
                with np.errstate(divide="ignore"):
                    log_w = np.log(w)
            resampled.append(do_resample)
            secs.append(time.perf_counter() - t0)
            if on_frame is not None:
                on_frame(k, mean)
        return FilterResult(np.array(means).reshape(-1, D), np.array(bests).reshape(-1, D), np.array(esss),
                            np.array(secs), np.array(resampled, bool), recovered)

