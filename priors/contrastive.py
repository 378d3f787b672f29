"""Contrastive-divergence helpers shared by the CRBM, the FCRBM and the deep (two-layer) CRBM: the training settings
they share (:class:`priors.settings.ContrastiveConfig`), shuffled mini-batches of windows, the momentum update with weight decay,
and the label-balanced window list.

Every random draw comes from the ``torch.Generator`` passed in (derived from the caller's numpy generator with
:func:`priors.common.torch_generator`).
"""
from __future__ import annotations

import functools
import math
from typing import Callable, Iterable, Iterator, TypeVar

import torch

from tracker.core.errors import InputError


_F = TypeVar("_F", bound=Callable)


def on_one_thread(train: _F) -> _F:
    """Run a contrastive-divergence training with torch on one thread, whatever the process's count, and restore
    the count after. Its products are of mini-batches of about a hundred windows, too small to share: on two
    cores one thread trains a CRBM about three times faster than two, to the same weights
    (docs/guide/training.md, "Large corpora")."""

    @functools.wraps(train)
    def wrapped(*args, **kwargs):
        threads = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            return train(*args, **kwargs)
        finally:
            torch.set_num_threads(threads)

    return wrapped  # type: ignore[return-value]


def minibatches(starts: torch.Tensor, batch_size: int, generator: torch.Generator) -> Iterator[torch.Tensor]:
    """Window start indices ``(M,)`` in a random order, ``batch_size`` at a time (one epoch)."""
    order = starts[torch.randperm(len(starts), generator=generator, device=starts.device)]
    for i in range(0, len(order), batch_size):
        yield order[i:i + batch_size]


def window_index(batch: torch.Tensor, length: int) -> torch.Tensor:
    """Frame indices ``B x length`` of the windows starting at ``batch`` ``(B,)`` (windows by indexing)."""
    return batch[:, None] + torch.arange(length, device=batch.device)


def momentum_step(params: dict[str, torch.Tensor], velocity: dict[str, torch.Tensor],
                  grads: dict[str, torch.Tensor], rates: dict[str, float], momentum: float, weight_decay: float,
                  decayed: Iterable[str]) -> None:
    """In place, for every name of ``params``: ``velocity = momentum * velocity + rate * (grad - weight_decay *
    param)`` (weight decay only for the ``decayed`` names), then ``param += velocity``. ``grads`` are ascent
    directions (the CD statistics, data minus reconstruction)."""
    decayed = set(decayed)
    for k, param in params.items():
        grad = grads[k] - weight_decay * param if k in decayed else grads[k]
        velocity[k] = momentum * velocity[k] + rates[k] * grad
        params[k] = param + velocity[k]


def finish_epoch(errors: list[float], err_sum: float, count: int, epoch: int, kind: str,
                 progress: Callable[[int, float], None] | None) -> None:
    """End epoch ``epoch`` (0-based) of a CD training: append its mean squared reconstruction error
    ``err_sum / count`` to ``errors``, refuse a diverged training (an :class:`InputError` saying what to change),
    and report ``progress(epoch + 1, error)``."""
    errors.append(err_sum / count)
    if not math.isfinite(errors[-1]):
        raise InputError(f"{kind} training diverged at epoch {epoch + 1} (reconstruction error is not finite); "
                         "lower the learning rate")
    if progress is not None:
        progress(epoch + 1, errors[-1])


def balanced_starts(starts: torch.Tensor, groups: torch.Tensor) -> torch.Tensor:
    """Window starts ``(M,)`` with those of every group (label index per window, ``(M,)``) repeated so that each
    group has about as many windows as the largest (Taylor & Hinton 2009 balance their styles by repeating
    the shorter sequences)."""
    counts = torch.bincount(groups)
    most = int(counts.max())
    parts = []
    for g in range(len(counts)):
        mine = starts[groups == g]
        if len(mine):
            parts.append(mine.repeat(max(1, round(most / len(mine)))))
    return torch.cat(parts)
