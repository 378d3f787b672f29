"""Silhouettes from the video itself: a median background plate finds a moving person, leaves out a smaller
mover, and refuses (one line) a person who never moves."""
from __future__ import annotations

import numpy as np
import pytest

from data_tools.sequences.sequence import read_sequence, write_image, write_sequence_header
from tracker.app.silhouettes import keep_person, view_masks, write_sequence_masks
from tracker.app.cli import main
from tracker.core.cameras import CameraRig, look_at
from tracker.core.errors import InputError

H, W, N = 60, 80, 12


def scene(move: bool = True, seed: int = 0):
    """``N`` frames of a textured room with a 14 x 30 px person walking across (standing still unless ``move``)
    and a 3 x 3 px distractor; returns the frames and the person's true masks."""
    rng = np.random.default_rng(seed)
    room = rng.integers(40, 200, (H, W, 3)).astype(np.uint8)
    room = np.repeat(np.repeat(room[::4, ::4], 4, 0), 4, 1)[:H, :W]
    frames, truth = [], []
    for k in range(N):
        img = room.astype(float) + rng.normal(0, 2.0, room.shape)
        x = 5 + (5 * k if move else 20)
        mask = np.zeros((H, W), bool)
        mask[20:50, x:x + 14] = True
        img[mask] = (230, 60, 60)
        img[5:8, 70 - k:73 - k] = 255  # a small mover far behind
        frames.append(np.clip(img, 0, 255).astype(np.uint8))
        truth.append(mask)
    return frames, truth


def test_median_plate_finds_the_moving_person_and_only_the_person():
    frames, truth = scene()
    masks = list(view_masks(lambda k: frames[k], N, "median"))
    iou = [(m & t).sum() / (m | t).sum() for m, t in zip(masks, truth)]
    assert min(iou) > 0.85
    assert not any(m[5:8].any() for m in masks)  # the distractor is not the largest region


def test_keep_person_keeps_the_largest_region():
    mask = np.zeros((30, 30), bool)
    mask[2:5, 2:5] = True
    mask[10:25, 10:20] = True
    kept = keep_person(mask, radius=1)
    assert kept[15, 15] and not kept[3, 3]
    assert not keep_person(np.zeros((5, 5), bool)).any()


def sequence(tmp_path, move: bool):
    frames, _ = scene(move)
    root = tmp_path / "seq"
    write_sequence_header(root, CameraRig([look_at("c0", (3000.0, 0.0, 1000.0), (0.0, 0.0, 900.0), W, H, 60.0)]),
                          {"fps": 30.0})
    for k, f in enumerate(frames):
        write_image(root / "images" / "c0" / f"{k:06d}.png", f)
    return root


def test_command_writes_masks_that_track_reads(tmp_path, capsys, monkeypatch):
    import tracker.app.silhouettes as silhouettes

    root = sequence(tmp_path, move=True)
    assert main(["silhouettes", str(root)]) == 0
    seq = read_sequence(root)
    assert seq.mask_paths is not None and seq.mask(3, 0).sum() > 0.8 * 14 * 30

    def no_model(seq):
        raise AssertionError("the default method was looked for (the person model run) before the refusal")

    monkeypatch.setattr(silhouettes, "default_method", no_model)
    assert main(["silhouettes", str(root)]) == 2
    assert "already has masks" in capsys.readouterr().err


def test_a_person_standing_still_is_refused_in_one_line(tmp_path):
    root = sequence(tmp_path, move=False)
    with pytest.raises(InputError, match="no person found in camera c0 at frame 0") as err:
        write_sequence_masks(read_sequence(root), "median")
    assert "masks of your own" in str(err.value)
    assert not (root / "masks").exists() and not (root / "masks.partial").exists()
