"""Training a deep CRBM greedily (Taylor 2009, Sec. 4.3): the first layer as a CRBM, then the second layer on the
first one's hidden activations (:mod:`priors.deep_crbm.model`)."""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from priors.common import epoch_checkpoint, read_model_file, torch_generator, torch_save_atomic
from priors.contrastive import finish_epoch, minibatches, momentum_step, on_one_thread, window_index
from priors.crbm.model import CRBM, CRBMModel, bernoulli
from priors.crbm.training import growth_orders, make_windows, train_crbm_prior, training_windows
from priors.crbm.file import model_from_document
from priors.deep_crbm.model import CHECKPOINT_FORMAT, DeepCRBMModel
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


@on_one_thread
def train_top(acts: torch.Tensor, follows: torch.Tensor, config: TopConfig, rng: np.random.Generator,
              progress: Callable[[int, float], None] | None = None,
              checkpoint: tuple[Callable[[CRBM, dict], None], int] | None = None,
              resume: dict | None = None) -> tuple[CRBM, list[float]]:
    """The second layer: a CRBM with binary visible units on the activations ``M x H1`` (windows of ``order + 1``
    consecutive rows of one clip), trained with CD-k (binary hidden samples drive the reconstructions, hidden
    probabilities in both phases' statistics) for ``config.epochs_for(windows)`` epochs; returns it and the
    reconstruction error per epoch. ``checkpoint = (save, every)`` and ``resume`` as for the CRBM
    (:func:`priors.crbm.training.train_crbm`)."""
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
    first_epoch = 0
    if resume is not None:
        top.load_state_dict(resume["params"])
        velocity = {k: resume["velocity"][k].to(device) for k in CRBM.PARAMS}
        g.set_state(resume["generator"])
        first_epoch, errors = int(resume["epoch"]), [float(e) for e in resume["reconstruction_errors"]]

    def training_state(epochs_done: int) -> dict:
        """Everything a resumed training needs after ``epochs_done`` epochs, copied."""
        return {"params": top.state_dict(), "epoch": epochs_done, "generator": g.get_state(),
                "velocity": {k: v.detach().cpu().clone() for k, v in velocity.items()},
                "reconstruction_errors": list(errors)}

    last = None if checkpoint is None else training_state(first_epoch)
    try:
        for epoch in range(first_epoch, cfg.epochs):
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
            last = epoch_checkpoint(checkpoint, top, training_state, epoch + 1, cfg.epochs)
    except KeyboardInterrupt:  # the state after the last finished epoch, for a resume to continue from
        if last is not None:
            top.load_state_dict(last["params"])
            checkpoint[0](top, last)
        raise
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
                          checkpoint: Path | None = None, resume: bool = False) -> DeepCRBMModel:
    """``train --prior deep-crbm``: the first layer as ``train --prior crbm`` trains it, then the second layer on
    its hidden activations. With ``checkpoint`` (a file) the training state is saved there every
    ``checkpoint_every`` epochs and when the training is interrupted (while the first layer trains, as the CRBM's
    checkpoint; then with the first layer's model in it); ``resume`` continues from it to the model an
    uninterrupted run gives."""
    t0 = time.perf_counter()
    crbm_options = {o.name for o in CRBM_TRAIN_OPTIONS}
    bottom_options = resolve_options("training crbm", CRBM_TRAIN_OPTIONS,
                                     {k: v for k, v in options.items() if k in crbm_options and v is not None})
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
    saved = _top_checkpoint(checkpoint) if resume else None
    if saved is not None:  # the first layer finished before: its model, and the draws its stages took
        bottom = model_from_document(saved["bottom"], checkpoint, "cpu")
        if saved.get("stage_orders") != orders or saved.get("top_order") != top_cfg.order:
            raise InputError("the checkpoint is not of this training (other orders)", checkpoint)
        for _ in orders:
            rng.integers(2 ** 62)
    else:
        bottom = train_crbm_prior(data, bottom_options, rng, None if progress is None else
                                  (lambda done, _, metrics: progress(done, total, metrics)), checkpoint, resume)
    seconds_before = 0.0 if saved is None else float(saved["seconds"])

    def save(top: CRBM, training_state: dict) -> None:
        torch_save_atomic({"format": CHECKPOINT_FORMAT, "bottom": bottom.to_document(), "stage_orders": orders,
                           "top_order": top_cfg.order, "seconds": seconds_before + time.perf_counter() - t0,
                           "training_state": training_state}, checkpoint)

    acts, follows = first_layer_activations(bottom, list(data.clips))
    before = total - top_epochs
    every = bottom_options["checkpoint_every"] or 0
    top, errors = train_top(acts, follows, top_cfg, rng, None if progress is None else
                            (lambda epoch, err: progress(before + epoch, total, {"second layer": err})),
                            None if checkpoint is None else (save, every),
                            None if saved is None else saved["training_state"])
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
    return DeepCRBMModel(bottom, top, replace(top_cfg, epochs=top_epochs), errors,
                         seconds_before + time.perf_counter() - t0)


def _top_checkpoint(path: Path | None) -> dict | None:
    """The checkpoint saved while the second layer trained, or None where the file is another (the first
    layer's, which the CRBM's training reads and checks)."""
    if path is None or not path.exists():
        return None
    try:
        return read_model_file(path, CHECKPOINT_FORMAT, "deep CRBM training checkpoint")
    except InputError:
        return None
