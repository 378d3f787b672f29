"""Sequential importance resampling with an N-order augmented state, optionally annealed: the engine.

Each frame (Taylor 2009, Sec. 6.3):

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

How a frame's likelihood becomes the weights and how the particles are redrawn is a strategy chosen once per
filter from the prior (:func:`tracker.engine.weighing.weighing_for`): plain SIR as above, or mixture tracking
for a prior whose particles are split into components kept apart (:mod:`tracker.engine.multiple_models`). The strategy
also says which particles annealing layers sharpen and redraw together.

If every weight is ``-inf`` (no particle explains the frame) the filter
records the frame as recovered, re-diffuses the particles around the last
estimate, and goes on; it never produces NaN.

The engine knows priors and likelihoods only through their interfaces
(:mod:`tracker.engine.prior`, :mod:`tracker.engine.likelihood`). Every random
draw comes from the one generator passed in. :meth:`ParticleFilter.start` and
:meth:`ParticleFilter.step` expose the loop one frame at a time (its whole
state is a :class:`FilterState`); :meth:`ParticleFilter.run` runs it over a
sequence of frames and returns what the caller asked to record, through
:func:`tracker.engine.pipeline.run_frames`: with ``workers > 0`` the filter
steps in a background thread while the calling thread reads and prepares the
next frame's observations, and further workers prepare frames ahead
(:class:`~tracker.engine.pipeline.Prefetcher`); preparation draws no random
numbers and the steps run in order, so the results are the same.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from tracker.core.blas import serial_blas
from tracker.engine.config import FilterConfig  # the filter's settings, declared with their options
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood, RefiningFrameLikelihood
from tracker.engine.pipeline import Prefetcher, run_frames  # Prefetcher: also importable from here
from tracker.engine.prior import MotionPrior, PriorState, label_for, restart, summarize
from tracker.engine.recording import DEFAULT_RECORD, FrameStep, Recording
from tracker.engine.resampling import SCHEMES
from tracker.engine.weighing import weighing_for
from tracker.engine.weights import LogWeights, effective_sample_size


@dataclass(frozen=True)
class FilterState:
    """Everything the filter carries from one frame to the next.

    ``history`` ``P x N x D``: each particle's last N poses, oldest first;
    ``prior_state``: the prior's own per-particle state; ``weights``: the
    log-weights carried into the next frame; ``recent_estimates`` ``N x D``: the
    last N estimates (where recovery restarts from); ``available``: how many
    history slots hold real poses (1..N); ``tracked``: frames tracked so far.
    """

    history: np.ndarray
    prior_state: PriorState
    weights: LogWeights
    recent_estimates: np.ndarray
    available: int
    tracked: int = 0


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


@dataclass
class Weighed:
    """One frame's particles weighed: the poses ``x`` ``P x D`` and the histories ``P x N x D`` they came from
    (both moved by annealing layers, or re-diffused), the prior's next state, the log-weights and the normalised
    weights ``(P,)``, and whether no particle explained the frame (the filter re-diffused)."""

    x: np.ndarray
    history: np.ndarray
    prior_state: PriorState
    weights: LogWeights
    normalised: np.ndarray
    recovered: bool


class ParticleFilter:
    """SIR over poses with the prior's order as the augmented-state length.

    ``weighing`` is the strategy that turns likelihoods into weights and resamples
    (:mod:`tracker.engine.weighing`), chosen from the prior."""

    def __init__(self, prior: MotionPrior, likelihood: Likelihood, config: FilterConfig,
                 rng: np.random.Generator):
        self.prior = prior
        self.likelihood = likelihood
        self.config = config.check()
        self.rng = rng
        self.resample = SCHEMES[config.resampling]
        self.weighing = weighing_for(prior, self.resample, self.config.n_particles)

    # -- one frame at a time -------------------------------------------------------------------------------

    def start(self, known: np.ndarray) -> FilterState:
        """The state before the first tracked frame, from the known poses ``n0 x D`` (newest last)."""
        known = np.atleast_2d(np.asarray(known, float))
        P, N = self.config.n_particles, self.prior.order
        recent = known[-N:]
        if len(recent) < N:  # pad the oldest slots with the earliest known pose
            recent = np.concatenate([np.repeat(recent[:1], N - len(recent), axis=0), recent])
        history = np.repeat(recent[None], P, axis=0)
        self.likelihood.start(known)
        prior_state = self.prior.start(known, P, self.rng)
        weights = self.weighing.start_weights(prior_state)
        return FilterState(history, prior_state, weights, recent.copy(), min(len(known), N))

    def step(self, state: FilterState, frame: Frame, load_seconds: float = 0.0,
             prepared: FrameLikelihood | None = None) -> tuple[FilterState, FrameStep]:
        """Track one frame: propose, weigh (annealed if configured), estimate, resample when due.

        ``prepared`` is the frame's likelihood already prepared (by a :class:`~tracker.engine.pipeline.Prefetcher`);
        ``load_seconds`` is the time spent waiting for the frame (seconds, recorded as its ``load`` time).
        """
        t0 = time.perf_counter()
        frame_lik = self.likelihood.prepare(frame) if prepared is None else prepared
        t1 = time.perf_counter()
        label = label_for(self.prior, state.available)
        weighed = self._weigh(state, frame_lik)
        W = weighed.normalised
        # (best a copy: a row of the particles would keep all of them alive in a recording of every frame)
        mean, best, ess = W @ weighed.x, weighed.x[int(np.argmax(W))].copy(), effective_sample_size(W)
        summary = summarize(self.prior, weighed.prior_state, W)
        new_state, resampled = self._resample(state, weighed, mean, ess)
        t2 = time.perf_counter()
        step = FrameStep(index=state.tracked, frame=frame.index, particles=weighed.x, weights=weighed.weights,
                         mean=mean, best=best, ess=ess, resampled=resampled, recovered=weighed.recovered,
                         seconds={"load": load_seconds, "observe": 0.0 if prepared is not None else t1 - t0,
                                  "filter": t2 - t1}, prior_label=label, prior_summary=summary)
        return new_state, step

    def _weigh(self, state: FilterState, frame_lik: FrameLikelihood) -> Weighed:
        """Every particle's next pose from the prior, given its own history and state (moved towards the frame's
        evidence first where the likelihood refines, :class:`~tracker.engine.likelihood.RefiningFrameLikelihood`),
        weighed by the frame: the likelihood of those poses (its ``evidence``), sharpened through the annealing layers when
        configured; re-diffused around the last estimate when no particle explains the frame; made weights by
        the strategy."""
        x, prior_state = self.prior.sample(state.history, state.available, state.prior_state, self.rng)
        if isinstance(frame_lik, RefiningFrameLikelihood):  # the prior's samples moved towards the evidence
            x = frame_lik.refine(x)
        history, carried = state.history, state.weights
        ll = evidence = frame_lik(x)
        if self.config.annealing_layers > 1:  # ll becomes the last layer's tempered log-likelihood
            x, history, prior_state, annealed = self._anneal(x, history, prior_state, ll, frame_lik)
            ll = annealed.log_w
        weighed = self.weighing.weigh(carried, ll, evidence, prior_state)
        recovered = weighed is None
        if recovered:  # no particle has any weight
            x, history, prior_state, carried, ll = self._recover(state, frame_lik)
            weighed = self.weighing.weigh(carried, ll, ll, prior_state)
        return Weighed(x, history, prior_state, *weighed, recovered)

    def _resample(self, state: FilterState, weighed: Weighed, mean: np.ndarray, ess: float
                  ) -> tuple[FilterState, bool]:
        """The state the next frame starts from: the histories moved on by the new poses, resampled by the
        strategy (due on every annealed frame, else when the effective sample size falls below the threshold),
        the prior's state reindexed with them; and whether it resampled."""
        cfg = self.config
        history = np.concatenate([weighed.history[:, 1:], weighed.x[:, None]], axis=1)
        recent = np.concatenate([state.recent_estimates[1:], mean[None]])
        due = cfg.annealing_layers > 1 or ess < cfg.ess_threshold * cfg.n_particles
        idx, carried, prior_state = self.weighing.resample(weighed.weights, weighed.normalised,
                                                           weighed.prior_state, due, self.rng)
        if idx is not None:
            history = history[idx]
        available = min(state.available + 1, self.prior.order)
        return (FilterState(history, prior_state, carried, recent, available, state.tracked + 1),
                idx is not None)

    def _anneal(self, x: np.ndarray, history: np.ndarray, prior_state: PriorState, ll: np.ndarray,
                frame_lik: FrameLikelihood) -> tuple[np.ndarray, np.ndarray, PriorState, LogWeights]:
        """Deutscher & Reid's layers: sharpen, resample, diffuse less each layer; the last layer's weights.

        Each of the strategy's groups of particles is annealed on its own (its exponents chosen on its particles,
        its positions redrawn from its own particles), so that a strategy that keeps components apart keeps
        their particles. The carried weights are left out of the layers: every annealed frame resamples, which
        leaves them equal within a group."""
        cfg = self.config
        diffusion = self.prior.diffusion_std()
        groups = self.weighing.groups(prior_state)

        def tempered(ll: np.ndarray) -> np.ndarray:
            out = np.full(len(ll), -np.inf)
            for g in groups:
                out[g] = choose_beta(ll[g], cfg.survival_rate) * ll[g]
            return out

        for m in range(cfg.annealing_layers - 1):
            if not np.any(np.isfinite(ll)):
                break
            log_w, idx = tempered(ll), np.arange(len(ll))
            for g in groups:
                if np.any(np.isfinite(log_w[g])):  # a group no particle of which fits is not resampled
                    idx[g] = g[self.resample(LogWeights(log_w[g]).normalised, self.rng, len(g))]
            x, history, ll = x[idx], history[idx], ll[idx]
            prior_state = self.prior.reindex(prior_state, idx)
            x = x + self.rng.standard_normal(x.shape) * diffusion * cfg.layer_diffusion_decay ** (m + 1)
            ll = frame_lik(x)
        return x, history, prior_state, LogWeights(tempered(ll))

    def _recover(self, state: FilterState, frame_lik: FrameLikelihood
                 ) -> tuple[np.ndarray, np.ndarray, PriorState, LogWeights, np.ndarray]:
        """No particle explains the frame: re-diffuse around the last estimate and restart the histories there,
        and the prior's own state from them. The new poses ``P x D``, histories, prior state, the carried
        log-weights a particle set starts with, and the frame's log-likelihood of the new poses (zero where
        nothing explains them either)."""
        P, D = state.history.shape[0], state.history.shape[2]
        x = state.recent_estimates[-1] + self.rng.standard_normal((P, D)) * self.prior.diffusion_std()
        history = np.repeat(state.recent_estimates[None], P, axis=0)
        ll = LogWeights(frame_lik(x)).log_w  # (a NaN value is a particle with no weight)
        ll = ll if np.any(np.isfinite(ll)) else np.zeros(P)
        prior_state = restart(self.prior, state.prior_state, state.recent_estimates, P, self.rng)
        return x, history, prior_state, self.weighing.start_weights(prior_state), ll

    # -- a whole sequence ----------------------------------------------------------------------------------

    @serial_blas()
    def run(self, known: np.ndarray, frames: Iterable[Frame],
            record: Iterable[str] | Mapping[str, Callable[[FrameStep], Any]] | Recording = DEFAULT_RECORD,
            on_frame: Callable[[FrameStep], None] | None = None, state: FilterState | None = None,
            on_state: Callable[[FilterState, Recording], None] | None = None,
            workers: int = 0) -> dict[str, np.ndarray]:
        """Track from the known poses ``n0 x D`` through ``frames``; returns the recorded quantities, one array
        each with tracked frames on the leading axis (see :mod:`tracker.engine.recording`).

        ``on_frame(step)`` sees every :class:`FrameStep` (particles and weights included); ``on_state(state,
        recording)`` sees the filter's whole state after every frame (for checkpoints). To continue an earlier
        run, pass its ``state`` and its :class:`Recording` as ``record``, restore the generator's state, and
        give only the frames not yet tracked. ``workers`` > 0 steps the filter in a background thread while the
        calling thread reads and prepares the next frame, and ``workers - 1`` more threads prepare frames
        further ahead (then a frame's ``load`` time is its reading and preparation, done while the frame before
        was filtered, and its ``observe`` time 0); 0 does everything in the calling thread, one frame at a time.
        The results are the same either way. numpy's BLAS runs on one thread throughout
        (:func:`tracker.core.blas.serial_blas`: the products of a filter step and of preparing a frame are
        small, and a parallel BLAS call leaves its threads spinning on the cores the likelihood's threads need).
        """
        recording = record if isinstance(record, Recording) else Recording(record)
        if state is None:
            state = self.start(known)
        else:  # a stopped run continued: the likelihood sees the known poses as at the start
            self.likelihood.start(known)
        return run_frames(self.step, state, frames, self.likelihood, recording, on_frame, on_state,
                          workers).result()
