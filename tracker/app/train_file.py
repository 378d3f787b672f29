"""A training that writes its model file, stopped (Ctrl-C, SIGTERM) and continued.

:func:`train_into` is :func:`tracker.train` writing the model to a file: every training file is read and
checked before anything is written; a resumable prior's training state is kept in ``MODEL.checkpoint`` (with
the training files' hashes beside it, ``MODEL.checkpoint.inputs.json``) every ``checkpoint_every`` epochs and
at a stop; ``resume=True`` continues from that state to the model an uninterrupted training gives (from the
beginning where the training stopped before its first checkpoint); the model file is written once, whole, at
the end. ``pose-tracker train`` is this call.
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Any, Callable, Iterable

from data_tools.io.files import atomic_path, check_not_inside, check_output_file, first_missing, undone_unless_started

log = logging.getLogger(__name__)

__all__ = ["TrainingStopped", "train_into", "checkpoint_of"]


class TrainingStopped(KeyboardInterrupt):
    """A training stopped (Ctrl-C, SIGTERM); ``resumable``: its state is kept at ``checkpoint`` for
    ``resume=True`` (False: the prior cannot resume, or it stopped before its first checkpoint)."""

    def __init__(self, checkpoint: Path, resumable: bool):
        super().__init__("training interrupted")
        self.checkpoint = checkpoint
        self.resumable = resumable


def checkpoint_of(out: str | Path) -> Path:
    """Where the training of the model file ``out`` keeps its state: ``OUT.checkpoint``."""
    out = Path(out)
    return out.with_name(out.name + ".checkpoint")


def train_into(out: str | Path, prior: str, mocap: str | Path | Iterable[str | Path], *,
               skeletons: Iterable[str | Path] | None = None, fps: float | None = 60.0,
               joint_maps: Any = None, seed: int = 0, progress: Callable | None = None, resume: bool = False,
               overwrite: bool = False, overwrite_flag: str = "overwrite=True", **options):
    """Train ``prior`` on ``mocap`` as :func:`tracker.train` does and write the model to ``out`` (see the
    module's text); returns the model. An existing ``out`` is refused unless ``overwrite`` (``overwrite_flag``:
    how the refusal says so); a stop raises :class:`TrainingStopped` after keeping what a resume needs."""
    from data_tools.motion.load import load_training_clips
    from tracker.app import api
    from tracker.app.plugins import prior_entry

    out = check_output_file(out, "the model file", new=not overwrite, overwrite_flag=overwrite_flag)
    files = [mocap] if isinstance(mocap, (str, Path)) else list(mocap)
    check_not_inside(out, {f"training file {i + 1}": f for i, f in enumerate([*files, *(skeletons or [])])})
    entry = prior_entry(prior)
    if entry.train is not None:  # a labels pattern or file is checked before any clip is read
        from data_tools.motion.corpus import is_label_source, label_source

        if is_label_source(options.get("labels")):
            label_source(options["labels"]).training_keys()
    clips = load_training_clips(files, skeletons, fps, joint_maps)  # every file read and checked first
    checkpoint = checkpoint_of(out)
    resuming = resume and (checkpoint.exists() or not entry.resumable)  # the latter refused by train
    if resume and not resuming:  # stopped before its first checkpoint: the whole training again
        log.info(f"no training checkpoint at {checkpoint}: training from the start")
    side = checkpoint.with_name(checkpoint.name + ".inputs.json")
    with undone_unless_started(first_missing(out), checkpoint, side) as work:  # refused: nothing stays behind
        def on_progress(done: int, total: int, metrics: dict) -> None:
            if not work["started"]:  # every setting checked: the training has begun
                work["started"] = True
                log.info(f"training a {prior} prior on {len(clips)} clip(s), "
                         f"{sum(len(c.poses) for c in clips)} frames at {clips[0].fps:g} fps")
            if progress is not None:
                progress(done, total, metrics)

        try:
            model = api.train(prior, clips, skeletons=skeletons, fps=clips[0].fps, seed=seed, progress=on_progress,
                              checkpoint=checkpoint, resume=resuming, **options)
        except KeyboardInterrupt:  # the training state at the stop (if any) stays for a resume
            work["started"] = True  # the model file is written only at the end: nothing else to undo
            if not checkpoint.exists():  # stopped before the training kept any state, or a prior that cannot resume
                side.unlink(missing_ok=True)
            raise TrainingStopped(checkpoint, checkpoint.exists()) from None
    with atomic_path(out) as tmp:
        model.save(tmp)
    return model
