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

A prior may split the particles into components that resampling keeps apart (mixture tracking, for a
discrete hypothesis such as the FCRBM's style label; :mod:`tracker.engine.mixture`): then the weights are
normalised within components and times the components' weights, and every frame resamples each component.
Annealing layers anneal each component on its own, and the components are weighed on the likelihood of the
prior's own samples, before the layers moved them.

If every weight is ``-inf`` (no particle explains the frame) the filter
records the frame as recovered, re-diffuses the particles around the last
estimate, and goes on; it never produces NaN.

The engine knows priors and likelihoods only through their interfaces
(:mod:`tracker.engine.prior`, :mod:`tracker.engine.likelihood`). Every random
draw comes from the one generator passed in. :meth:`ParticleFilter.start` and
:meth:`ParticleFilter.step` expose the loop one frame at a time (its whole
state is a :class:`FilterState`); :meth:`ParticleFilter.run` runs it over a
sequence of frames and returns what the caller asked to record. With
``workers > 0`` the filter steps in a background thread while the calling
thread reads and prepares the next frame's observations, and further workers
prepare frames ahead (:class:`Prefetcher`); preparation draws no random
numbers and the steps run in order, so the results are the same.
"""
from __future__ import annotations

import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Any, Callable, Iterable, Iterator, Mapping

import numpy as np

from tracker.core.blas import serial_blas
from tracker.engine.config import FilterConfig  # the filter's settings, declared with their options
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.mixture import Mixture, mixture_weights, resample_components
from tracker.engine.prior import MotionPrior, PriorState
from tracker.engine.recording import DEFAULT_RECORD, FrameStep, Recording
from tracker.engine.resampling import SCHEMES
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
class Proposal:
    """One frame's proposal: poses ``x`` ``P x D`` drawn by the prior from the histories ``P x N x D``, the
    prior's next state, and the mixture's components (None: plain SIR)."""

    x: np.ndarray
    history: np.ndarray
    prior_state: PriorState
    mix: Mixture | None


@dataclass
class Weighed(Proposal):
    """A proposal weighed by the frame (annealed, recovered, mixed): the log-weights and the normalised weights
    ``(P,)``, and whether no particle explained the frame (the filter re-diffused)."""

    weights: LogWeights = None
    normalised: np.ndarray = None
    recovered: bool = False


class ParticleFilter:
    """SIR over poses with the prior's order as the augmented-state length."""

    def __init__(self, prior: MotionPrior, likelihood: Likelihood, config: FilterConfig,
                 rng: np.random.Generator):
        self.prior = prior
        self.likelihood = likelihood
        self.config = config.check()
        self.rng = rng
        self.resample = SCHEMES[config.resampling]

    # -- one frame at a time -------------------------------------------------------------------------------

    def start(self, known: np.ndarray) -> FilterState:
        """The state before the first tracked frame, from the known poses ``n0 x D`` (newest last)."""
        known = np.atleast_2d(np.asarray(known, float))
        P, N = self.config.n_particles, self.prior.order
        recent = known[-N:]
        if len(recent) < N:  # pad the oldest slots with the earliest known pose
            recent = np.concatenate([np.repeat(recent[:1], N - len(recent), axis=0), recent])
        history = np.repeat(recent[None], P, axis=0)
        prior_state = self.prior.start(known, P, self.rng)
        mix = self._mixture(prior_state)
        weights = LogWeights.uniform(P) if mix is None else mix.start_weights()
        return FilterState(history, prior_state, weights, recent.copy(), min(len(known), N))

    def _mixture(self, prior_state: PriorState) -> Mixture | None:
        """The prior's components for ``prior_state`` (checked), or None for plain SIR."""
        mix = self.prior.mixture(prior_state)
        return None if mix is None else mix.check(self.config.n_particles)

    def step(self, state: FilterState, frame: Frame, load_seconds: float = 0.0,
             prepared: FrameLikelihood | None = None) -> tuple[FilterState, FrameStep]:
        """Track one frame: propose, weigh (annealed if configured), estimate, resample when due.

        ``prepared`` is the frame's likelihood already prepared (by a :class:`Prefetcher`); ``load_seconds`` is
        the time spent waiting for the frame (seconds, recorded as its ``load`` time).
        """
        t0 = time.perf_counter()
        frame_lik = self.likelihood.prepare(frame) if prepared is None else prepared
        t1 = time.perf_counter()
        label = self.prior.label_for(state.available)
        proposal = self._propose(state)
        weighed = self._weigh(state, proposal, frame_lik)
        W = weighed.normalised
        # (best a copy: a row of the particles would keep all of them alive in a recording of every frame)
        mean, best, ess = W @ weighed.x, weighed.x[int(np.argmax(W))].copy(), effective_sample_size(W)
        summary = self.prior.summarize(weighed.prior_state, W)
        new_state, resampled = self._resample(state, weighed, mean, ess)
        t2 = time.perf_counter()
        step = FrameStep(index=state.tracked, frame=frame.index, particles=weighed.x, weights=weighed.weights,
                         mean=mean, best=best, ess=ess, resampled=resampled, recovered=weighed.recovered,
                         seconds={"load": load_seconds, "observe": 0.0 if prepared is not None else t1 - t0,
                                  "filter": t2 - t1}, prior_label=label, prior_summary=summary)
        return new_state, step

    def _propose(self, state: FilterState) -> "Proposal":
        """Every particle's next pose from the prior, given its own history and state."""
        mix = self._mixture(state.prior_state)
        x, prior_state = self.prior.sample(state.history, state.available, state.prior_state, self.rng)
        return Proposal(x, state.history, prior_state, mix)

    def _weigh(self, state: FilterState, proposal: "Proposal", frame_lik: FrameLikelihood) -> "Weighed":
        """The proposal weighed by the frame: the likelihood of the prior's samples (the mixture's components
        are judged on these), sharpened through the annealing layers when configured, re-diffused around the
        last estimate when no particle explains the frame, and within a mixture's components times the
        components' weights."""
        x, history, prior_state, mix = proposal.x, proposal.history, proposal.prior_state, proposal.mix
        ll = evidence = frame_lik(x)
        if self.config.annealing_layers > 1:  # ll becomes the last layer's tempered log-likelihood
            x, history, prior_state, annealed = self._anneal(x, history, prior_state, ll, frame_lik, mix)
            ll = annealed.log_w
        weights = state.weights.add(ll)  # carried weights: uniform after an annealed frame, unless a mixture's
        recovered = not weights.any_finite
        carried_in = state.weights
        if recovered:
            x, history, weights = self._recover(state, frame_lik)
            prior_state = self.prior.restart(state.prior_state, state.recent_estimates, self.config.n_particles,
                                             self.rng)
            mix = self._mixture(prior_state)
            if mix is not None:  # the components start afresh, each with an equal weight
                carried_in, ll = mix.start_weights(), weights.log_w
                evidence = ll
        if mix is None:
            return Weighed(x, history, prior_state, mix, weights, weights.normalised, recovered)
        W = mixture_weights(carried_in, ll, mix, evidence)  # within components, times the components' weights
        if not W.any():  # only the recovery's all-minus-infinity frame gets here: its particles, unweighted
            W = np.full(len(W), 1.0 / len(W))
        weights = LogWeights(np.log(W, out=np.full(len(W), -np.inf), where=W > 0))
        return Weighed(x, history, prior_state, mix, weights, W, recovered)

    def _resample(self, state: FilterState, weighed: "Weighed", mean: np.ndarray, ess: float
                  ) -> tuple[FilterState, bool]:
        """The state the next frame starts from: the histories moved on by the new poses, resampled when due
        (every annealed frame and every mixture frame, else when the effective sample size falls below the
        threshold), the prior's state reindexed with them; and whether it resampled."""
        cfg, W, mix = self.config, weighed.normalised, weighed.mix
        history = np.concatenate([weighed.history[:, 1:], weighed.x[:, None]], axis=1)
        prior_state = weighed.prior_state
        recent = np.concatenate([state.recent_estimates[1:], mean[None]])
        resampled = cfg.annealing_layers > 1 or mix is not None or ess < cfg.ess_threshold * cfg.n_particles
        if mix is not None:  # every frame, each component redrawn from all particles (the IMM mixing step)
            idx, carried = resample_components(W, mix, self.rng, self.resample)
            history = history[idx]
            prior_state = self.prior.relabel(self.prior.reindex(prior_state, idx), mix.component)
        elif resampled:
            idx = self.resample(W, self.rng)
            history = history[idx]
            prior_state = self.prior.reindex(prior_state, idx)
            carried = LogWeights.uniform(cfg.n_particles)
        else:
            carried = weighed.weights.renormalised()
        available = min(state.available + 1, self.prior.order)
        return FilterState(history, prior_state, carried, recent, available, state.tracked + 1), bool(resampled)

    def _anneal(self, x: np.ndarray, history: np.ndarray, prior_state: PriorState, ll: np.ndarray,
                frame_lik: FrameLikelihood, mix: Mixture | None = None
                ) -> tuple[np.ndarray, np.ndarray, PriorState, LogWeights]:
        """Deutscher & Reid's layers: sharpen, resample, diffuse less each layer; the last layer's weights.

        With a mixture every component is annealed on its own (its exponents chosen on its particles, its
        positions redrawn from its own particles), so the components keep their particles. The carried weights
        are left out of the layers: they are equal within a component (:meth:`Mixture.start_weights`,
        :func:`~tracker.engine.mixture.resample_components`), and uniform without a mixture, since every annealed
        frame resamples."""
        cfg = self.config
        diffusion = self.prior.diffusion_std()
        groups = ([np.arange(len(ll))] if mix is None
                  else [np.flatnonzero(mix.component == c) for c in range(mix.n_components)])

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
                if np.any(np.isfinite(log_w[g])):  # a component no particle of which fits is not resampled
                    idx[g] = g[self.resample(LogWeights(log_w[g]).normalised, self.rng, len(g))]
            x, history, ll = x[idx], history[idx], ll[idx]
            prior_state = self.prior.reindex(prior_state, idx)
            x = x + self.rng.standard_normal(x.shape) * diffusion * cfg.layer_diffusion_decay ** (m + 1)
            ll = frame_lik(x)
        return x, history, prior_state, LogWeights(tempered(ll))

    def _recover(self, state: FilterState, frame_lik: FrameLikelihood
                 ) -> tuple[np.ndarray, np.ndarray, LogWeights]:
        """No particle explains the frame: re-diffuse around the last estimate, restart the histories there (and
        the prior's own state from them, in :meth:`step`)."""
        P, D = state.history.shape[0], state.history.shape[2]
        x = state.recent_estimates[-1] + self.rng.standard_normal((P, D)) * self.prior.diffusion_std()
        history = np.repeat(state.recent_estimates[None], P, axis=0)
        ll = frame_lik(x)
        return x, history, LogWeights(ll if np.any(np.isfinite(ll)) else np.zeros(P))

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
        state = self.start(known) if state is None else state

        clock = [time.perf_counter()]  # when the frame before was done (its callbacks not counted)

        def finish(new_state: FilterState, step: FrameStep) -> FilterState:
            step = replace(step, seconds={**step.seconds, "wall": time.perf_counter() - clock[0]})
            recording.add(step)
            if on_frame is not None:
                on_frame(step)
            if on_state is not None:
                on_state(new_state, recording)
            clock[0] = time.perf_counter()
            return new_state

        if workers <= 0:
            with Prefetcher(frames, self.likelihood, 0) as source:
                while True:
                    t0 = time.perf_counter()
                    item = source.next()
                    if item is None:
                        break
                    state = finish(*self.step(state, item[0], time.perf_counter() - t0, item[1]))
            return recording.result()
        # Pipelined: a filter thread steps frame t while this thread reads and prepares frame t+1 (image decoding
        # stays on this thread, see Prefetcher: its stderr redirection could swallow what the filter thread printed
        # meanwhile, which is nothing in normal operation), and the workers beyond the first prepare further ahead.
        # Steps run one at a time in frame order and every callback runs here between them, so the results and
        # the generator's draws are those of the loop above.
        with ThreadPoolExecutor(1, thread_name_prefix="filter") as stepper, \
                Prefetcher(frames, self.likelihood, workers - 1) as source:
            item, load = self._next_prepared(source)
            while item is not None:
                stepping = stepper.submit(self.step, state, item[0], load, item[1])
                try:
                    following, load = self._next_prepared(source)
                except Exception as exc:  # raised once the frames before it are done, as in the loop above
                    following, failure = None, exc
                else:
                    failure = None
                state = finish(*stepping.result())
                if failure is not None:
                    raise failure
                item = following
        return recording.result()

    def _next_prepared(self, source: "Prefetcher") -> tuple[tuple[Frame, FrameLikelihood] | None, float]:
        """The next frame from ``source`` with its observations prepared (here, when ``source`` did not), and
        the seconds that took; None at the end."""
        t0 = time.perf_counter()
        item = source.next()
        if item is not None and item[1] is None:
            item = (item[0], self.likelihood.prepare(item[0]))
        return item, time.perf_counter() - t0


class Prefetcher:
    """Frames in order, each with its likelihood prepared ahead in background threads.

    The calling thread reads the frames (image decoding stays there: readers may briefly redirect the
    process's stderr to silence image libraries, which would swallow another thread's messages) up to
    ``workers`` frames ahead of the one it hands out, and ``workers`` threads prepare them with
    ``likelihood.prepare`` meanwhile. An exception raised while reading or preparing a frame is raised by
    :meth:`next` when that frame is due, so the frames before it are processed exactly as without
    prefetching. ``workers = 0`` reads frame by frame and leaves preparation to the caller. Use as a context
    manager (it stops the threads).
    """

    def __init__(self, frames: Iterable[Frame], likelihood: Likelihood, workers: int = 0):
        self.iterator: Iterator[Frame] = iter(frames)
        self.likelihood = likelihood
        self.workers = max(0, int(workers))
        self.pool = ThreadPoolExecutor(self.workers, thread_name_prefix="prepare") if self.workers else None
        self.pending: deque[tuple[Frame, Future] | BaseException] = deque()
        self.ended = False

    def __enter__(self) -> "Prefetcher":
        return self

    def __exit__(self, *exc) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=False, cancel_futures=True)

    def next(self) -> tuple[Frame, FrameLikelihood | None] | None:
        """The next frame with its prepared likelihood (None when not prefetching), or None at the end."""
        if self.pool is None:
            frame = next(self.iterator, None)
            return None if frame is None else (frame, None)
        if not self.pending:
            self._read()
        item = self.pending.popleft() if self.pending else None
        while len(self.pending) < self.workers and not self.ended:
            self._read()  # while the frame about to be handed out is still being prepared
        if item is None or isinstance(item, BaseException):
            if item is not None:
                raise item
            return None
        frame, future = item
        return frame, future.result()

    def _read(self) -> None:
        try:
            frame = next(self.iterator, None)
        except Exception as exc:  # raised when this frame is due
            self.ended = True
            self.pending.append(exc)
            return
        if frame is None:
            self.ended = True
        else:
            self.pending.append((frame, self.pool.submit(self.likelihood.prepare, frame)))
