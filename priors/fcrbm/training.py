"""Training an FCRBM by contrastive divergence (Taylor & Hinton 2009, Sec. 4.2; the model is
:mod:`priors.fcrbm.model`)."""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from priors.common import epoch_checkpoint, torch_generator
from priors.contrastive import balanced_starts, finish_epoch, minibatches, momentum_step, on_one_thread, window_index
from priors.crbm.model import bernoulli
from priors.crbm.training import history_noise_scale, make_windows, window_starts
from priors.fcrbm.model import FCRBM, FCRBMModel, one_hot
from priors.settings import FCRBMConfig
from tracker.core.errors import InputError
from tracker.core.representation import step_rms


@on_one_thread
def train_fcrbm(clips: Sequence[np.ndarray], clip_labels: Sequence[str], config: FCRBMConfig, fps: float,
                dof_names: Sequence[str], body_model: str = "15-cone", sources: Sequence[str] = (),
                progress: Callable[[int, float], None] | None = None, device: str = "cpu", *,
                rng: np.random.Generator, labels: Sequence[str] | None = None,
                checkpoint: tuple[Callable[[FCRBMModel, dict], None], int] | None = None,
                resume: dict | None = None) -> FCRBMModel:
    """Train an FCRBM on pose clips (each ``T x D`` at ``fps``), clip ``i`` labelled ``clip_labels[i]``, with CD-k;
    every random draw comes from ``rng``. ``labels`` fixes the label order (default: first appearance).
    ``progress(epoch, reconstruction_error)`` is called after every epoch. ``checkpoint = (save, every)`` and
    ``resume`` as for the CRBM (:func:`priors.crbm.training.train_crbm`): the training state is saved every
    ``every`` epochs and when the training is interrupted, and a resume continues to the model an uninterrupted
    run gives."""
    cfg = config.check()
    sources = list(sources) or [f"clip {i + 1}" for i in range(len(clips))]
    if len(clip_labels) != len(clips):
        raise InputError(f"{len(clip_labels)} label(s) for {len(clips)} training clip(s)")
    labels = list(labels) if labels is not None else list(dict.fromkeys(clip_labels))
    t0 = time.perf_counter()
    g = torch_generator(rng, device)
    data = make_windows(clips, cfg.order, dof_names)
    frames = data.frames.to(device)
    K, N, H = frames.shape[1], cfg.order, cfg.hidden
    window_label = window_labels([len(c) for c in clips], clip_labels, labels, data.starts)
    for i, label in enumerate(labels):
        if not bool((window_label == i).any()):
            short = [s for s, t in zip(sources, clip_labels) if t == label]
            raise InputError(f"label {label!r} has no clip longer than {N + 2} frames to train order {N} on",
                             ", ".join(Path(s).name for s in short) or None)
    starts = balanced_starts(data.starts, window_label) if cfg.balance else data.starts
    cfg = replace(cfg, epochs=cfg.epochs_for(len(starts)))  # the update budget
    frame_label = torch.zeros(len(frames), dtype=torch.long)
    frame_label[data.starts] = window_label
    frame_label = frame_label.to(device)
    starts = starts.to(device)
    net = FCRBM(K, H, N, len(labels), cfg.features, cfg.factors, generator=g, device=device)
    noise = history_noise_scale(data).to(device) if cfg.history_noise == "auto" else \
        torch.full((K,), float(cfg.history_noise), device=device)
    noise = noise.repeat(N)
    rates = {k: cfg.autoregressive_learning_rate if k in FCRBM.SLOW else cfg.learning_rate for k in FCRBM.PARAMS}
    ar_share = cfg.autoregressive_learning_rate / cfg.learning_rate if cfg.learning_rate else 0.0
    velocity = {k: torch.zeros_like(v) for k, v in net.params.items()}
    model = FCRBMModel(fcrbm=net, labels=labels, normaliser=data.normaliser, config=cfg, fps=fps,
                       body_model=body_model, dof_names=list(dof_names), sources=sources,
                       clip_labels=list(clip_labels), pose_step_rms=step_rms(clips))
    first_epoch, seconds_before = 0, 0.0
    if resume is not None:
        net.load_state_dict(resume["params"])
        velocity = {k: resume["velocity"][k].to(device) for k in FCRBM.PARAMS}
        g.set_state(resume["generator"])
        first_epoch, seconds_before = int(resume["epoch"]), float(resume["seconds"])
        model.reconstruction_errors = [float(e) for e in resume["reconstruction_errors"]]

    def training_state(epochs_done: int) -> dict:
        """Everything a resumed training needs after ``epochs_done`` epochs, copied."""
        model.training_seconds = seconds_before + time.perf_counter() - t0
        return {"params": net.state_dict(), "epoch": epochs_done, "generator": g.get_state(),
                "velocity": {k: v.detach().cpu().clone() for k, v in velocity.items()},
                "reconstruction_errors": list(model.reconstruction_errors), "seconds": model.training_seconds}

    last = None if checkpoint is None else training_state(first_epoch)
    try:
        for epoch in range(first_epoch, cfg.epochs):
            err_sum, count = 0.0, 0
            for batch in minibatches(starts, cfg.batch_size, g):
                window = frames[window_index(batch, N + 1)]
                v0, n = window[:, -1], len(batch)
                hist = window[:, :-1].reshape(n, N * K)
                if cfg.history_noise:
                    hist = hist + torch.randn(hist.shape, generator=g, device=device) * noise
                y = one_hot(frame_label[batch], len(labels))
                shared = net.conditioning(hist, y)  # computed once for the biases and both phases
                s = shared[1]
                a_hat, b_hat = net.biases(hist, s, shared[2:])
                h = bernoulli(net.hidden_probabilities(v0, s, b_hat), g)
                for _ in range(cfg.cd_k):
                    vk = net.visible_means(h, s, a_hat)
                    h = bernoulli(net.hidden_probabilities(vk, s, b_hat), g)
                pos = net.free_energy_gradients(v0, hist, y, shared)
                neg = net.free_energy_gradients(vk, hist, y, shared)
                ascent = {k: neg[k] - pos[k] for k in pos}  # lower F at the data, raise it at the reconstructions
                ar = ascent.pop("Z_autoregressive")
                ascent["Z"] = ascent["Z"] - ar + ar_share * ar
                momentum_step(net.params, velocity, ascent, rates, cfg.momentum, cfg.weight_decay, FCRBM.DECAYED)
                err_sum += float(((v0 - vk) ** 2).sum())
                count += n * K
            finish_epoch(model.reconstruction_errors, err_sum, count, epoch, "FCRBM", progress)
            last = epoch_checkpoint(checkpoint, model, training_state, epoch + 1, cfg.epochs)
    except KeyboardInterrupt:  # the state after the last finished epoch, for a resume to continue from
        if last is not None:
            net.load_state_dict(last["params"])
            model.reconstruction_errors = list(last["reconstruction_errors"])
            model.training_seconds = last["seconds"]
            checkpoint[0](model, last)
        raise
    model.training_seconds = seconds_before + time.perf_counter() - t0
    return model


def window_labels(clip_lengths: Sequence[int], clip_labels: Sequence[str], labels: Sequence[str],
                  starts: torch.Tensor) -> torch.Tensor:
    """The label index ``(M,)`` of every window starting at ``starts`` ``(M,)`` (into the features of clips of
    ``clip_lengths`` frames concatenated, :func:`~priors.crbm.training.make_windows`): its clip's label."""
    ends = torch.tensor(np.cumsum([length - 1 for length in clip_lengths]))
    clip_of = torch.searchsorted(ends, starts, right=True)
    return torch.tensor([list(labels).index(t) for t in clip_labels])[clip_of]


def training_windows(clip_lengths: Sequence[int], clip_labels: Sequence[str], order: int, balance: bool) -> int:
    """How many windows (the rarer labels' repeated when ``balance``) an FCRBM of ``order`` trains on per epoch
    from clips of ``clip_lengths`` frames labelled ``clip_labels``: what
    :meth:`~priors.settings.ContrastiveConfig.epochs_for` counts."""
    starts = window_starts(clip_lengths, order)
    if not len(starts) or not balance:
        return len(starts)
    return len(balanced_starts(starts, window_labels(clip_lengths, clip_labels, list(dict.fromkeys(clip_labels)),
                                                     starts)))
