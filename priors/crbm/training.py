"""Training a CRBM (Taylor 2009, Sec. 4.2) on pose clips, and ``train --prior crbm``.

CD-k on mini-batches of randomly permuted (N+1)-frame windows, built by indexing (frames are never copied into
windows), with momentum, weight decay on W, A and B, learning rate 1e-3 (1e-5 for the autoregressive A), the
mean-field approximations of Sec. 4.2.4 (expected visible values; binary hidden states driving reconstructions
and the positive statistics, hidden probabilities in the negative statistics), Gaussian noise on the history
(Sec. 6.4.1; by default per dimension the 99th percentile of the frame-to-frame change) and an optional sparsity
target (Sec. 4.5.4, cross-entropy to a damped average activation). One ``torch.Generator``, seeded from the
numpy generator passed in, drives every random draw.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from priors.common import epoch_checkpoint, read_model_file, torch_generator, torch_save_atomic
from priors.contrastive import finish_epoch, minibatches, momentum_step, on_one_thread
from priors.crbm.file import model_from_document
from priors.crbm.model import CHECKPOINT_FORMAT, CRBM, INPUT_SETTINGS, CRBMConfig, CRBMModel, bernoulli
from priors.settings import PACE_SPREAD_FOR_INPUT
from tracker.core.errors import InputError
from tracker.core.representation import FeatureNormaliser, clip_features, clip_log_pace, step_rms
from tracker.engine.registry import TrainingData


@dataclass
class WindowData:
    """Normalised features of all training clips, concatenated ``T x K``, and the start indices ``(M,)`` of
    every (N+1)-frame window that lies inside one clip and avoids each clip's last frame (whose velocities
    are only a repeat of the step before)."""

    frames: torch.Tensor
    starts: torch.Tensor
    normaliser: FeatureNormaliser
    #: Each frame's log pace ``(T,)`` (:func:`~tracker.core.representation.clip_log_pace`), when asked for.
    pace: np.ndarray | None = None


def make_windows(clips: Sequence[np.ndarray], order: int, dof_names: Sequence[str],
                 normaliser: FeatureNormaliser | None = None, pace_window: int | None = None) -> WindowData:
    """The training windows of ``clips``; with ``pace_window`` (frames) also every frame's log pace."""
    normed, normaliser = clip_features(clips, dof_names, normaliser)
    pace = None if pace_window is None else np.concatenate([clip_log_pace(c, pace_window) for c in clips])
    starts = window_starts([len(c) for c in clips], order)
    if not len(starts):
        raise InputError(f"the training clips are too short for order {order} (need more than {order + 2} frames)")
    return WindowData(torch.tensor(np.concatenate(normed), dtype=torch.float32), starts, normaliser, pace)


def window_starts(clip_lengths: Sequence[int], order: int) -> torch.Tensor:
    """The start indices ``(M,)`` of the (``order`` + 1)-frame windows of clips of ``clip_lengths`` frames, into
    their features concatenated (each clip keeps ``T_i - 1`` frames, :func:`make_windows`)."""
    starts, offset = [np.zeros(0, np.int64)], 0
    for length in clip_lengths:
        starts.append(offset + np.arange(max(length - 1 - order, 0)))
        offset += max(length - 1, 0)
    return torch.tensor(np.concatenate(starts))


def training_windows(clip_lengths: Sequence[int], order: int, validation: float) -> int:
    """How many windows a CRBM of ``order`` trains on from clips of ``clip_lengths`` frames, after the validation
    split (:func:`split_validation`): what :meth:`~priors.settings.ContrastiveConfig.epochs_for` counts."""
    starts = window_starts(clip_lengths, order)
    if not len(starts):
        return 0
    return len(split_validation(starts, clip_lengths, order, validation)[0])



def history_noise_scale(data: WindowData) -> torch.Tensor:
    """Per-dimension noise for the history: the 99th percentile of |frame-to-frame change| in the data."""
    idx = data.starts
    diffs = (data.frames[idx + 1] - data.frames[idx]).abs()
    return torch.quantile(diffs, 0.99, dim=0)



@on_one_thread
def train_crbm(clips: Sequence[np.ndarray], config: CRBMConfig, fps: float, dof_names: Sequence[str],
               body_model: str = "15-cone", sources: Sequence[str] = (),
               progress: Callable[[int, float], None] | None = None,
               checkpoint: tuple[Callable[[CRBMModel, dict], None], int] | None = None, device: str = "cpu", *,
               rng: np.random.Generator, resume: dict | None = None) -> CRBMModel:
    """Train a CRBM on pose clips (each ``T x D`` at ``fps``) with CD-k; every random draw comes from ``rng``.

    ``progress(epoch, reconstruction_error)`` is called after every epoch; ``checkpoint = (save, every)``
    calls ``save(model, training_state)`` every ``every`` epochs (0: never), and, when the training is interrupted
    (``KeyboardInterrupt``: Ctrl-C, or SIGTERM as the command line answers it), with the state after the last
    finished epoch before the interrupt goes on; ``resume`` (such a ``training_state``, with the model's weights
    in it) continues from there to the model an uninterrupted run gives.
    """
    cfg = config.check()
    t0 = time.perf_counter()
    g = torch_generator(rng, device)
    data = make_windows(clips, cfg.order, dof_names, pace_window=pace_window(fps) if cfg.pace_input else None)
    frames = data.frames.to(device)
    K, N, H, C = frames.shape[1], cfg.order, cfg.hidden, int(cfg.pace_input)
    crbm = CRBM(K, H, N, generator=g, device=device, n_context=C)
    noise = history_noise_scale(data).to(device) if cfg.history_noise == "auto" else \
        torch.full((K,), float(cfg.history_noise), device=device)
    noise = torch.cat([torch.zeros(C, device=device), noise.repeat(N)])  # the pace input is given, not noisy
    pace_label, pace = None, None
    if cfg.pace_input:
        pace_label = (float(np.mean(data.pace)), max(float(np.std(data.pace)), 1e-3))
        pace = torch.tensor((data.pace - pace_label[0]) / pace_label[1], dtype=torch.float32, device=device)
    steps = torch.arange(N + 1, device=device)
    velocity = {k: torch.zeros_like(getattr(crbm, k)) for k in CRBM.PARAMS}
    rates = {"W": cfg.learning_rate, "A": cfg.autoregressive_learning_rate, "B": cfg.learning_rate,
             "a": cfg.learning_rate, "b": cfg.learning_rate}
    activity = torch.full((H,), cfg.sparsity_target or 0.0, device=device)
    model = CRBMModel(crbm=crbm, normaliser=data.normaliser, config=cfg, fps=fps, body_model=body_model,
                      dof_names=list(dof_names), sources=list(sources), pose_step_rms=step_rms(clips),
                      pace_label=pace_label)
    starts, held_out = split_validation(data.starts, [len(c) for c in clips], N, cfg.validation)
    starts, held_out = starts.to(device), held_out.to(device)
    cfg = model.config = replace(cfg, epochs=cfg.epochs_for(len(starts)))  # the update budget

    def windows(window_starts: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The frames to predict ``B x K`` and their conditioning inputs ``B x (C + N K)`` (the pace of the frame
        to predict, then the history) of the windows starting at ``window_starts`` ``(B,)``: windows by indexing."""
        idx = window_starts[:, None] + steps  # B x (N+1) frame indices
        window = frames[idx]
        hist = window[:, :-1].reshape(len(idx), N * K)
        if pace is not None:
            hist = torch.cat([pace[idx[:, -1], None], hist], dim=1)
        return window[:, -1], hist

    def held_out_error() -> float:
        """Mean squared one-step prediction error (normalised units) of the free-energy best guess on the
        held-out windows."""
        v, hist = windows(held_out)
        return float(((crbm.best_guess(hist) - v) ** 2).mean())

    best = {"error": math.inf, "params": None}
    first_epoch, seconds_before = 0, 0.0
    if resume is not None:
        crbm.load_state_dict(resume["params"])
        velocity = {k: resume["velocity"][k].to(device) for k in CRBM.PARAMS}
        activity = resume["activity"].to(device)
        g.set_state(resume["generator"])
        first_epoch = int(resume["epoch"])
        model.reconstruction_errors = [float(e) for e in resume["reconstruction_errors"]]
        seconds_before = float(resume["seconds"])
        if "best" in resume:
            best = {"error": float(resume["best"]["error"]), "params": resume["best"]["params"]}
            model.validation_errors = [list(map(float, x)) for x in resume["best"]["errors"]]
            model.best_epoch = int(resume["best"]["epoch"])

    def training_state(epochs_done: int) -> dict:
        """Everything a resumed training needs after ``epochs_done`` epochs, copied (later epochs leave it as
        it was)."""
        model.training_seconds = seconds_before + time.perf_counter() - t0
        return {"params": crbm.state_dict(), "epoch": epochs_done,
                "velocity": {k: v.detach().cpu().clone() for k, v in velocity.items()},
                "activity": activity.detach().cpu().clone(), "generator": g.get_state(),
                "reconstruction_errors": list(model.reconstruction_errors), "seconds": model.training_seconds,
                **({"best": {**best, "errors": list(model.validation_errors), "epoch": model.best_epoch}}
                   if len(held_out) else {})}

    last = None if checkpoint is None else training_state(first_epoch)
    try:
        for epoch in range(first_epoch, cfg.epochs):
            err_sum, count = 0.0, 0
            for batch in minibatches(starts, cfg.batch_size, g):
                v0, hist = windows(batch)
                if cfg.history_noise:
                    hist = hist + torch.randn(hist.shape, generator=g, device=device) * noise
                a_hat, b_hat = crbm.biases(hist)
                p0 = crbm.hidden_probabilities(v0, b_hat)
                h0 = bernoulli(p0, g)
                h = h0
                for _ in range(cfg.cd_k):
                    vk = a_hat + h @ crbm.W.T
                    pk = crbm.hidden_probabilities(vk, b_hat)
                    h = bernoulli(pk, g)
                n = len(v0)
                dv, dh = v0 - vk, h0 - pk
                grads = {"W": (v0.T @ h0 - vk.T @ pk) / n, "A": hist.T @ dv / n, "B": hist.T @ dh / n,
                         "a": dv.mean(0), "b": dh.mean(0)}
                if cfg.sparsity_target is not None:
                    activity = 0.9 * activity + 0.1 * p0.mean(0)
                    push = cfg.sparsity_cost * (cfg.sparsity_target - activity)
                    grads["b"] = grads["b"] + push
                    grads["W"] = grads["W"] + v0.mean(0)[:, None] * push[None, :]
                    grads["B"] = grads["B"] + hist.mean(0)[:, None] * push[None, :]
                params = crbm.params()
                momentum_step(params, velocity, grads, rates, cfg.momentum, cfg.weight_decay, CRBM.DECAYED)
                crbm.set_params(params)
                err_sum += float(((v0 - vk) ** 2).sum())
                count += n * K
            finish_epoch(model.reconstruction_errors, err_sum, count, epoch, "CRBM", progress)
            if len(held_out) and ((epoch + 1) % cfg.validation_every == 0 or epoch + 1 == cfg.epochs):
                error = held_out_error()
                model.validation_errors.append([epoch + 1, error])
                if error < best["error"]:
                    best = {"error": error, "params": crbm.state_dict()}
                    model.best_epoch = epoch + 1
            last = epoch_checkpoint(checkpoint, model, training_state, epoch + 1, cfg.epochs)
    except KeyboardInterrupt:  # the state after the last finished epoch, for a resume to continue from
        if last is not None:
            crbm.load_state_dict(last["params"])
            model.reconstruction_errors = list(last["reconstruction_errors"])
            model.validation_errors = list(last.get("best", {}).get("errors", model.validation_errors))
            model.training_seconds = last["seconds"]
            checkpoint[0](model, last)
        raise
    if best["params"] is not None:  # the weights of the best held-out check
        crbm.load_state_dict(best["params"])
    model.training_seconds = seconds_before + time.perf_counter() - t0
    return model


def split_validation(starts: torch.Tensor, clip_lengths: Sequence[int], order: int, fraction: float
                     ) -> tuple[torch.Tensor, torch.Tensor]:
    """The training windows' starts ``(M,)`` (indices into the clips' frames concatenated, clips of
    ``clip_lengths`` frames; a window predicts the frame ``order`` after its start) split into those for training
    and those held out: windows predicting a frame in the last ``fraction`` of their clip are held out (none when
    ``fraction`` is 0). Held-out windows are whole stretches of motion rather than frames scattered between
    training frames, which would flatter the check."""
    if fraction <= 0:
        return starts, starts[:0]
    s = starts.cpu().numpy()
    held = np.zeros(len(s), bool)
    offset = 0
    for n in clip_lengths:
        held |= (s + order >= offset + int(round((1 - fraction) * n))) & (s < offset + n)
        offset += n
    if held.all() or not held.any():
        raise InputError(f"a validation fraction of {fraction:g} leaves no windows to "
                         f"{'train on' if held.all() else 'hold out'}; the clips are too short")
    return starts[torch.from_numpy(~held)], starts[torch.from_numpy(held)]




def paces_vary(clips: Sequence[np.ndarray], fps: float) -> bool:
    """Whether the clips' frames (each clip ``T x D`` at ``fps``) vary in pace enough for a pace input
    (:data:`PACE_SPREAD_FOR_INPUT`)."""
    paces = np.concatenate([clip_log_pace(c, pace_window(fps)) for c in clips])
    return bool(np.std(paces) >= PACE_SPREAD_FOR_INPUT)




def pace_window(fps: float) -> int:
    """Frames of the centred window a training frame's pace is averaged over: one second."""
    return max(int(round(fps)), 1)



def parse_history_noise(value: str | float) -> str | float:
    """The ``history_noise`` training option: 'auto', or a number of normalised units in [0, 100]; anything else
    is an :class:`InputError` saying so."""
    if value == "auto":
        return value
    try:
        noise = float(value)
    except (TypeError, ValueError):
        raise InputError(f"history noise must be 'auto' or a number, got {value!r}") from None
    if not 0 <= noise <= 100:
        raise InputError(f"history noise must lie in [0, 100] (normalised units), got {value!r}")
    return noise


def train_crbm_prior(data: TrainingData, options: dict, rng: np.random.Generator,
                     progress: Callable[[int, int, dict], None] | None = None,
                     checkpoint: Path | None = None, resume: bool = False) -> CRBMModel:
    """``train --prior crbm``: a CRBM of ``options['order']`` on the clips of ``data``. With ``checkpoint`` (a file)
    the training state is saved there every ``checkpoint_every`` epochs and when the training is interrupted;
    ``resume`` continues from it to the model an uninterrupted run gives."""
    noise = parse_history_noise(options["history_noise"])
    pace_input = options["pace_input"]
    if pace_input is None:  # auto: only clips of several paces can teach the model what a pace means
        pace_input = paces_vary(list(data.clips), data.fps)
    config = CRBMConfig(order=options["order"], hidden=options["hidden"], epochs=options["epochs"],
                        cd_k=options["cd_k"], batch_size=options["batch_size"], updates=options["updates"],
                        history_noise=noise,
                        sparsity_target=options["sparsity"], pace_input=pace_input,
                        validation=options["validation"]).check()
    grow = growth_orders(options["grow_from"], config.order)
    every = options["checkpoint_every"] or 0
    orders = grow + [config.order]
    lengths = [len(c) for c in data.clips]
    epochs = [config.epochs_for(training_windows(lengths, o, config.validation)) for o in orders]
    total = sum(epochs)
    done: list[CRBMModel] = []
    state = None
    if resume:  # the growth models finished before, and the training state of the one in progress
        if checkpoint is None or not checkpoint.exists():
            raise InputError("no training checkpoint to resume from", checkpoint)
        doc = read_model_file(checkpoint, CHECKPOINT_FORMAT, "CRBM training checkpoint")
        saved = doc.get("config", {})
        if "training_state" not in doc or doc.get("stage_orders") != orders \
                or any(bool(saved.get(key, False)) != getattr(config, key) for key in INPUT_SETTINGS):
            raise InputError("the checkpoint is not of this training (other orders, another "
                             f"{' or '.join(INPUT_SETTINGS.values())}, or a finished model)", checkpoint)
        done = [model_from_document(g, checkpoint, "cpu") for g in doc["growth"]]
        state = doc["training_state"]
        for _ in done:  # the draws the finished stages took from rng
            rng.integers(2 ** 62)

    def save(stage_model: CRBMModel, training_state: dict) -> None:
        from copy import copy

        snapshot = copy(stage_model)
        snapshot.growth = list(done)
        doc = {**snapshot.to_document(), "format": CHECKPOINT_FORMAT, "training_state": training_state,
               "stage_orders": orders}
        torch_save_atomic(doc, checkpoint)  # a model is never half-written: the rename is atomic

    first = len(done)  # the stage the resumed state belongs to
    for i in range(first, len(orders)):  # the lower orders first, on the same clips, each with its own draws
        report = None if progress is None else (
            lambda epoch, err, before=sum(epochs[:i]): progress(before + epoch, total, {"reconstruction": err}))
        model = train_crbm(list(data.clips), replace(config, order=orders[i]), data.fps,
                           data.body_model.dof_names, data.body_model.name, list(data.sources), report,
                           None if checkpoint is None else (save, every), rng=rng,
                           resume=state if i == first else None)
        if i < len(grow):
            done.append(model)
    model.growth = done
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
    return model


def growth_orders(text: str, order: int) -> list[int]:
    """The lower orders named by ``grow_from`` ("1", "1,3" or "none") that are below ``order``."""
    if str(text).strip().lower() == "none":
        return []
    try:
        orders = sorted({int(t) for t in str(text).split(",") if t.strip()})
    except ValueError:
        raise InputError(f"grow_from must be 'none' or comma-separated orders like '1,3', got {text!r}") from None
    if any(o < 1 for o in orders):
        raise InputError(f"grow_from orders must be at least 1, got {text!r}")
    return [o for o in orders if o < order]



