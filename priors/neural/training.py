"""Training the neural prior on pose clips, and ``train --prior neural``.

Maximum likelihood by Adam on mini-batches of randomly permuted (N+1)-frame windows (built by indexing, as the
CRBM's: :func:`priors.crbm.training.make_windows`), the learning rate annealed on a cosine from its setting to 0
over the epochs. Each window's history is cut to a random length of 1 .. N frames (the older slots masked), so
the network draws from one known frame on, and carries Gaussian noise (the history the tracker gives it is its
own noisy draws). The last ``validation`` of each clip is held out; the weights of the epoch with the least
held-out negative log-likelihood are kept. One ``torch.Generator``, seeded from the numpy generator passed in,
drives every random draw (the initial weights included), so a seed fixes the model, and a training stopped and
resumed from its checkpoint reaches the weights an uninterrupted one does.
"""
from __future__ import annotations

import copy
import math
import time
from dataclasses import asdict
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from priors.common import epoch_checkpoint, read_model_file, torch_generator, torch_save_atomic
from priors.crbm.training import (
    history_noise_scale, make_windows, pace_window, paces_vary, parse_history_noise, split_validation,
)
from priors.neural.model import CHECKPOINT_FORMAT, NeuralModel, build_net
from priors.neural.settings import NeuralConfig
from tracker.core.errors import InputError
from tracker.core.representation import step_rms
from tracker.engine.registry import TrainingData

#: The auto history noise: this fraction of the CRBM's (the 99th percentile of each feature's frame-to-frame
#: change).
AUTO_NOISE_FRACTION = 0.25


def train_neural(clips: Sequence[np.ndarray], config: NeuralConfig, fps: float, dof_names: Sequence[str],
                 body_model: str = "15-cone", sources: Sequence[str] = (),
                 progress: Callable[[int, dict], None] | None = None,
                 checkpoint: tuple[Callable[[NeuralModel, dict], None], int] | None = None, *,
                 rng: np.random.Generator, resume: dict | None = None) -> NeuralModel:
    """Train the network on pose clips (each ``T x D`` at ``fps``); every random draw comes from ``rng``.

    ``progress(epoch, {"nll": ..., "held_out_nll": ...})`` after every epoch (negative log-likelihood per frame,
    normalised units); ``checkpoint = (save, every)`` calls ``save(model, training_state)`` every ``every`` epochs
    (0: never) and, when the training is interrupted (``KeyboardInterrupt``), with the state after the last
    finished epoch; ``resume`` (such a state) continues from there to the model an uninterrupted run gives."""
    cfg = config.check()
    t0 = time.perf_counter()
    g = torch_generator(rng, "cpu")
    data = make_windows(clips, cfg.order, dof_names, pace_window=pace_window(fps) if cfg.pace_input else None)
    frames = data.frames
    K, N, C = frames.shape[1], cfg.order, int(cfg.pace_input)
    with torch.random.fork_rng(devices=[]):  # the initial weights from the training's own generator
        torch.manual_seed(int(torch.randint(0, 2 ** 62, (1,), generator=g)))
        net = build_net(cfg, K, C)
    noise = AUTO_NOISE_FRACTION * history_noise_scale(data) if cfg.history_noise == "auto" else \
        torch.full((K,), float(cfg.history_noise))
    noise = noise.repeat(N)
    pace_label, pace = None, None
    if cfg.pace_input:
        pace_label = (float(np.mean(data.pace)), max(float(np.std(data.pace)), 1e-3))
        pace = torch.tensor((data.pace - pace_label[0]) / pace_label[1], dtype=torch.float32)
    model = NeuralModel(net=net, normaliser=data.normaliser, config=cfg, fps=fps, body_model=body_model,
                        dof_names=list(dof_names), sources=list(sources), pose_step_rms=step_rms(clips),
                        pace_label=pace_label)
    starts, held_out = split_validation(data.starts, [len(c) for c in clips], N, cfg.validation)
    steps = torch.arange(N + 1)
    optimiser = torch.optim.Adam(net.parameters(), lr=cfg.learning_rate)

    def windows(window_starts: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The frames to predict ``B x K`` and their conditioning ``B x (C + N K)`` (the pace of the frame to
        predict, then the history, oldest first)."""
        idx = window_starts[:, None] + steps
        window = frames[idx]
        hist = window[:, :-1].reshape(len(idx), N * K)
        if pace is not None:
            hist = torch.cat([pace[idx[:, -1], None], hist], dim=1)
        return window[:, -1], hist

    def held_out_nll() -> float:
        """Mean negative log-likelihood per frame of the held-out windows, with their whole histories."""
        with torch.no_grad():
            total = sum(float(-net.log_prob(*windows(b)).sum()) for b in held_out.split(4096))
        return total / len(held_out)

    best = {"error": math.inf, "params": None}
    first_epoch, seconds_before = 0, 0.0
    if resume is not None:
        net.load_state_dict(resume["params"])
        optimiser.load_state_dict(resume["optimiser"])
        g.set_state(resume["generator"])
        first_epoch = int(resume["epoch"])
        model.reconstruction_errors = [float(e) for e in resume["reconstruction_errors"]]
        model.validation_errors = [[float(e), float(x)] for e, x in resume["validation_errors"]]
        model.best_epoch = int(resume["best_epoch"])
        best = {"error": float(resume["best_error"]), "params": resume["best_params"]}
        seconds_before = float(resume["seconds"])

    def training_state(epochs_done: int) -> dict:
        """Everything a resumed training needs after ``epochs_done`` epochs, copied."""
        model.training_seconds = seconds_before + time.perf_counter() - t0
        return {"params": copy.deepcopy(net.state_dict()), "optimiser": copy.deepcopy(optimiser.state_dict()),
                "generator": g.get_state(), "epoch": epochs_done,
                "reconstruction_errors": list(model.reconstruction_errors),
                "validation_errors": [list(x) for x in model.validation_errors], "best_epoch": model.best_epoch,
                "best_error": best["error"], "best_params": best["params"], "seconds": model.training_seconds}

    last = None if checkpoint is None else training_state(first_epoch)
    try:
        for epoch in range(first_epoch, cfg.epochs):
            for group in optimiser.param_groups:  # cosine annealing, a function of the epoch alone
                group["lr"] = cfg.learning_rate * 0.5 * (1 + math.cos(math.pi * epoch / cfg.epochs))
            total, count = 0.0, 0
            order = starts[torch.randperm(len(starts), generator=g)]
            for batch in order.split(cfg.batch_size):
                v, hist = windows(batch)
                hist = hist.clone()
                hist[:, C:] += torch.randn(len(batch), N * K, generator=g) * noise
                lengths = torch.randint(1, N + 1, (len(batch),), generator=g)
                loss = -net.log_prob(v, hist, lengths).mean()
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                total += float(loss.detach()) * len(batch)
                count += len(batch)
            model.reconstruction_errors.append(total / count)
            if not math.isfinite(model.reconstruction_errors[-1]):
                raise InputError(f"neural prior training diverged at epoch {epoch + 1} (the loss is not finite); "
                                 "lower the learning rate")
            report = {"nll": model.reconstruction_errors[-1]}
            if len(held_out):
                error = held_out_nll()
                model.validation_errors.append([epoch + 1, error])
                report["held_out_nll"] = error
                if error < best["error"]:
                    best = {"error": error, "params": copy.deepcopy(net.state_dict())}
                    model.best_epoch = epoch + 1
            if progress is not None:
                progress(epoch + 1, report)
            last = epoch_checkpoint(checkpoint, model, training_state, epoch + 1, cfg.epochs)
    except KeyboardInterrupt:  # the state after the last finished epoch, for a resume to continue from
        if last is not None:
            net.load_state_dict(last["params"])
            model.reconstruction_errors = list(last["reconstruction_errors"])
            model.validation_errors = list(last["validation_errors"])
            model.best_epoch = last["best_epoch"]
            model.training_seconds = last["seconds"]
            checkpoint[0](model, last)
        raise
    if best["params"] is not None:
        net.load_state_dict(best["params"])
    model.training_seconds = seconds_before + time.perf_counter() - t0
    return model


def train_neural_prior(data: TrainingData, options: dict, rng: np.random.Generator,
                       progress: Callable[[int, int, dict], None] | None = None,
                       checkpoint: Path | None = None, resume: bool = False) -> NeuralModel:
    """``train --prior neural``: the network of ``options`` on the clips of ``data``. With ``checkpoint`` (a file)
    the training state is saved there every ``checkpoint_every`` epochs and when the training is interrupted;
    ``resume`` continues from it to the model an uninterrupted run gives."""
    pace_input = options["pace_input"]
    if pace_input is None:  # auto: only clips of several paces can teach the model what a pace means
        pace_input = paces_vary(list(data.clips), data.fps)
    config = NeuralConfig(order=options["order"], hidden=options["hidden"], layers=options["layers"],
                          components=options["components"], epochs=options["epochs"],
                          batch_size=options["batch_size"], learning_rate=options["learning_rate"],
                          history_noise=parse_history_noise(options["history_noise"]), pace_input=bool(pace_input),
                          validation=options["validation"]).check()
    state = None
    if resume:
        if checkpoint is None or not checkpoint.exists():
            raise InputError("no training checkpoint to resume from", checkpoint)
        doc = read_model_file(checkpoint, CHECKPOINT_FORMAT, "neural prior training checkpoint")
        saved = doc.get("config", {})
        if "training_state" not in doc or saved != asdict(config):
            raise InputError("the checkpoint is not of this training (other settings, or a finished model)",
                             checkpoint)
        state = doc["training_state"]

    def save(model: NeuralModel, training_state: dict) -> None:
        doc = {**model.to_document(), "format": CHECKPOINT_FORMAT, "training_state": training_state}
        torch_save_atomic(doc, checkpoint)  # never half-written: the rename is atomic

    report = None if progress is None else (lambda epoch, values: progress(epoch, config.epochs, values))
    saving = None if checkpoint is None else (save, options["checkpoint_every"] or 0)
    model = train_neural(list(data.clips), config, data.fps, data.body_model.dof_names, data.body_model.name,
                         list(data.sources), report, saving, rng=rng, resume=state)
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
    return model

