"""Training a deep CRBM greedily (Taylor 2009, Sec. 4.3): the first layer as a CRBM, then the second layer on the
first one's hidden activations (:mod:`priors.deep_crbm.model`)."""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from priors.common import torch_generator
from priors.contrastive import finish_epoch, minibatches, momentum_step, window_index
from priors.crbm.model import CRBM, CRBMModel, bernoulli
from priors.crbm.training import growth_orders, make_windows, train_crbm_prior, training_windows
from priors.deep_crbm.model import DeepCRBMModel
from priors.settings import CRBM_TRAIN_OPTIONS, CRBMConfig, TopConfig
from tracker.core.errors import InputError
from tracker.engine.registry import TrainingData, resolve_options


def first_layer_activations(model: CRBMModel, clips: Sequence[np.ndarray]) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean-field hidden probabilities ``M x H1`` of the first layer driven by the clips (one row per frame with
    ``N`` frames of history, clips concatenated), and a bool ``(M,)`` that is true where a row continues the
    previous row's clip (the next frame of the same clip)."""
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


def train_top(acts: torch.Tensor, follows: torch.Tensor, config: TopConfig, rng: np.random.Generator,
              progress: Callable[[int, float], None] | None = None) -> tuple[CRBM, list[float]]:
    """The second layer: a CRBM with binary visible units on the activations ``M x H1`` (windows of ``order + 1``
    consecutive rows of one clip), trained with CD-k (binary hidden samples drive the reconstructions, hidden
    probabilities in both phases' statistics) for ``config.epochs_for(windows)`` epochs; returns it and the
    reconstruction error per epoch."""
    cfg = config.check()
    device = acts.device
    g = torch_generator(rng, device)
    H1, N = acts.shape[1], cfg.order
    ends = torch.nonzero(run_lengths(follows) >= N + 1).flatten()
    if len(ends) == 0:
        raise InputError(f"the training clips are too short for a second layer of order {N} on top of the first")
    starts = (ends - N).to(device)
    cfg = replace(cfg, epochs=cfg.epochs_for(len(starts)))  # the update budget
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


def run_lengths(follows: torch.Tensor) -> torch.Tensor:
    """The length ``(M,)`` of the run of consecutive rows ending at each row, from ``follows`` ``(M,)`` (true
    where a row continues the previous row's clip)."""
    index = torch.arange(len(follows))
    first = torch.where(follows, torch.zeros_like(index), index)  # each run's first row, where a run starts
    return index - torch.cummax(first, 0).values + 1


def top_windows(clip_lengths: Sequence[int], bottom_order: int, top_order: int) -> int:
    """How many windows the second layer of ``top_order`` trains on above a first layer of ``bottom_order``, from
    clips of ``clip_lengths`` frames: what :meth:`~priors.settings.ContrastiveConfig.epochs_for` counts."""
    return sum(max(length - 1 - bottom_order - top_order, 0) for length in clip_lengths)


def train_deep_crbm_prior(data: TrainingData, options: dict, rng: np.random.Generator,
                          progress: Callable[[int, int, dict], None] | None = None,
                          checkpoint: Path | None = None) -> DeepCRBMModel:
    """``train --prior deep-crbm``: the first layer as ``train --prior crbm`` trains it, then the second layer on
    its hidden activations."""
    t0 = time.perf_counter()
    crbm_options = {o.name for o in CRBM_TRAIN_OPTIONS}
    bottom_options = resolve_options("training crbm", CRBM_TRAIN_OPTIONS,
                                     {k: v for k, v in options.items() if k in crbm_options and v is not None})
    bottom_options["checkpoint_every"] = None
    bottom_options["pace_input"] = False  # the second layer is trained on, and samples through, a plain first layer
    top_cfg = TopConfig(order=options["top_order"], hidden=options["top_hidden"], epochs=options["top_epochs"],
                        cd_k=bottom_options["cd_k"], batch_size=bottom_options["batch_size"],
                        updates=bottom_options["updates"]).check()
    lengths = [len(c) for c in data.clips]
    orders = growth_orders(bottom_options["grow_from"], bottom_options["order"]) + [bottom_options["order"]]
    bottom_cfg = CRBMConfig(epochs=bottom_options["epochs"], batch_size=bottom_options["batch_size"],
                            updates=bottom_options["updates"])
    top_epochs = top_cfg.epochs_for(top_windows(lengths, bottom_options["order"], top_cfg.order))
    total = sum(bottom_cfg.epochs_for(training_windows(lengths, o, bottom_options["validation"]))
                for o in orders) + top_epochs
    bottom = train_crbm_prior(data, bottom_options, rng, None if progress is None else
                              (lambda done, _, metrics: progress(done, total, metrics)))
    acts, follows = first_layer_activations(bottom, list(data.clips))
    before = total - top_epochs
    top, errors = train_top(acts, follows, top_cfg, rng, None if progress is None else
                            (lambda epoch, err: progress(before + epoch, total, {"second layer": err})))
    return DeepCRBMModel(bottom, top, replace(top_cfg, epochs=top_epochs), errors, time.perf_counter() - t0)
