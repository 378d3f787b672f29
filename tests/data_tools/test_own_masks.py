"""A sequence folder of one's own footage may give foreground masks (``masks/<camera>/NNNNNN.png``) instead of
background plates; the likelihood then scores the masks as silhouettes."""
import shutil

import cv2
import numpy as np
import pytest

from data_tools.sequences.sequence import read_sequence
from tracker.core.errors import InputError


@pytest.fixture
def masked_walk(synthetic_walk, tmp_path):
    """The synthetic walk without its background plates, with the renderer's exact masks written instead."""
    root = tmp_path / "walk"
    shutil.copytree(synthetic_walk.root, root)
    shutil.rmtree(root / "background")
    names = read_sequence(root).rig.names
    for view, name in enumerate(names):
        (root / "masks" / name).mkdir(parents=True)
        for frame, masks in enumerate(synthetic_walk.masks):
            cv2.imwrite(str(root / "masks" / name / f"{frame:06d}.png"), masks[view].astype(np.uint8) * 255)
    return root, synthetic_walk.masks


def test_masks_are_read_as_the_frames_silhouettes(masked_walk):
    root, masks = masked_walk
    seq = read_sequence(root)
    frame = seq.frame(3, [0, 2])
    assert frame.backgrounds is None or all(b is None for b in frame.backgrounds)
    np.testing.assert_array_equal(frame.masks[0], masks[3][0])
    np.testing.assert_array_equal(frame.masks[1], masks[3][2])


def test_tracking_on_masks_follows_the_walk(masked_walk):
    import tracker

    root, _ = masked_walk
    result = tracker.track(root, "zero-velocity", particles=200, seed=0, annealing_layers=1)
    assert np.isfinite(result.mean_error) and result.mean_error < 80  # mm, the person is found in the masks


def test_a_missing_mask_frame_is_refused_naming_it(masked_walk):
    root, _ = masked_walk
    name = read_sequence(root).rig.names[1]
    (root / "masks" / name / "000004.png").unlink()
    with pytest.raises(InputError, match="frame 4 is missing|has 5 frames"):
        read_sequence(root)
