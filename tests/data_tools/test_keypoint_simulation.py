"""The simulated detector (noise, outliers, swaps, misses, confidences; seeded) and the robust triangulation of
its keypoints (noise-free points come back exactly, outliers are dropped, swaps relabelled), the temporal
median and the TRC file of the triangulated keypoints."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from data_tools.motion.trc import read_trc
from data_tools.sequences.keypoint_file import read_keypoints, write_keypoints
from data_tools.vision.keypoints.simulate import (
    DetectorNoise, simulate_detections, simulate_detector, simulate_sequence_keypoints,
)
from data_tools.vision.keypoints.triangulate import (
    TRC_NAMES, default_max_error_px, median_filter, triangulate_keypoints, write_keypoints_trc,
)
from data_tools.vision.landmarks import triangulate
from tests.data_tools.test_landmarks import distorted_rig
from tracker.core.body import fifteen_cone_model
from tracker.core.cameras import default_rig
from tracker.core.errors import InputError
from tracker.core.keypoints import KEYPOINT_INDEX, KEYPOINTS, SWAP_GROUPS, keypoint_positions

#: The 12 limb joints the accuracy is measured on.
LIMBS = [KEYPOINT_INDEX[f"{side}_{joint}"] for side in ("left", "right")
         for joint in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]
EXACT = DetectorNoise(noise_mm=0.0, noise_floor_px=0.0, outlier_rate=0.0, swap_rate=0.0, miss_rate=0.0,
                      view_miss_rate=0.0)


def poses(frames: int, seed: int = 0) -> tuple[object, np.ndarray]:
    """The default body and ``frames`` poses about the capture area's centre: any heading, every joint angle
    moved by a Gaussian of 0.3 rad."""
    model = fifteen_cone_model()
    rng = np.random.default_rng(seed)
    q = np.tile(model.rest_pose(), (frames, 1))
    q[:, :2] = rng.uniform(-1000.0, 1000.0, (frames, 2))
    q[:, 5] = rng.uniform(-np.pi, np.pi, frames)
    q[:, 6:] += rng.normal(0.0, 0.3, (frames, q.shape[1] - 6))
    return model, q


def truth(frames: int, seed: int = 0) -> np.ndarray:
    """The keypoints ``T x K x 3`` (mm) of :func:`poses`."""
    model, q = poses(frames, seed)
    return keypoint_positions(model, q)


def limb_error(points: np.ndarray, true: np.ndarray) -> float:
    """Mean distance (mm) over the limb joints placed."""
    return float(np.nanmean(np.linalg.norm(points[:, LIMBS] - true[:, LIMBS], axis=-1)))


@pytest.mark.parametrize("rig", [default_rig(4), distorted_rig()], ids=["default", "distorted"])
def test_noise_free_detections_triangulate_back_to_the_truth(rig):
    X = truth(20)
    points = simulate_detections(rig, X, np.random.default_rng(0), EXACT)
    assert (points[..., 2] > 0.3).all()  # every point seen, with an inlier's confidence
    found = triangulate_keypoints(rig, points)
    assert np.abs(found.points - X).max() < 1e-6
    assert found.used.all() and np.nanmax(found.errors) < 1e-6 and not found.swapped.any()


def test_robust_triangulation_at_the_default_noise_and_with_many_outliers():
    rig, X = default_rig(4), truth(150)
    points = simulate_detections(rig, X, np.random.default_rng(1))
    robust = triangulate_keypoints(rig, points)
    assert robust.max_error_px == pytest.approx(15.0 * 480 / 1080)
    assert limb_error(robust.points, X) < 36.0  # measured 29-32 mm over seeds
    assert np.isfinite(robust.points[:, LIMBS, 0]).mean() > 0.98
    assert (robust.mean_error[np.isfinite(robust.points[..., 0])] <= robust.max_error_px).all()
    # A fifth of the points outliers: the robust points stay close, the plain DLT over every view does not.
    points = simulate_detections(rig, X, np.random.default_rng(1), DetectorNoise(outlier_rate=0.2))
    robust = limb_error(triangulate_keypoints(rig, points).points, X)
    naive = limb_error(triangulate(rig, points[..., :2], points[..., 2] > 0), X)
    assert robust < 65.0 and naive > 150.0 and robust < 0.4 * naive  # measured about 55 and 205 mm


def test_swaps_happen_at_the_stated_rate_and_are_relabelled():
    rig, X = default_rig(4), truth(300, seed=2)
    noise = DetectorNoise(noise_mm=0.0, noise_floor_px=0.0, outlier_rate=0.0, swap_rate=0.05, miss_rate=0.0,
                          view_miss_rate=0.0)
    sim = simulate_detector(rig, X, np.random.default_rng(3), noise)
    n = sim.swapped.size  # 300 frames x 4 views x 3 groups
    assert abs(sim.swapped.sum() - 0.05 * n) < 4.0 * np.sqrt(0.05 * 0.95 * n)
    # A swapped group's left points lie where the right ones project, and the other way.
    projected, _ = rig.project(X)
    for g, (left, right) in enumerate(SWAP_GROUPS):
        li, ri = [KEYPOINT_INDEX[k] for k in left], [KEYPOINT_INDEX[k] for k in right]
        t, v = np.nonzero(sim.swapped[:, :, g])
        assert np.allclose(sim.points[t, v][:, li, :2], projected[t, v][:, ri])
        assert np.allclose(sim.points[t, v][:, ri, :2], projected[t, v][:, li])
        t, v = np.nonzero(~sim.swapped[:, :, g])
        assert np.allclose(sim.points[t, v][:, li, :2], projected[t, v][:, li])
    # The swaps that matter (far enough apart to spoil the points) are relabelled, and few others.
    found = triangulate_keypoints(rig, sim.points)
    right = (found.swapped & sim.swapped).sum()
    assert right >= 0.4 * sim.swapped.sum() and right >= 0.9 * found.swapped.sum()
    errors = np.linalg.norm(found.points - X, axis=-1)
    kept = np.linalg.norm(triangulate_keypoints(rig, sim.points, fix_swaps=False).points - X, axis=-1)
    assert np.nanmedian(errors) < 1e-6 and np.nanmean(errors) < 0.8 * np.nanmean(kept)


def test_the_same_seed_gives_the_same_detections():
    rig, X = default_rig(3), truth(30)
    first = simulate_detections(rig, X, np.random.default_rng(7))
    assert np.array_equal(first, simulate_detections(rig, X, np.random.default_rng(7)), equal_nan=True)
    assert not np.array_equal(first, simulate_detections(rig, X, np.random.default_rng(8)), equal_nan=True)
    # One rate changed leaves every other draw as it was: the inliers' noise is the same.
    more = simulate_detector(rig, X, np.random.default_rng(7), DetectorNoise(outlier_rate=0.3))
    base = simulate_detector(rig, X, np.random.default_rng(7))
    same = ~more.outliers & ~base.outliers & ~base.dropped
    assert same.sum() > 0.5 * same.size
    assert np.array_equal(more.points[same], base.points[same])


def test_misses_give_confidence_zero_and_nan():
    rig, X = default_rig(4), truth(200)
    X[:5, KEYPOINT_INDEX["nose"]] += (0.0, 0.0, 10000.0)  # 10 m up: outside every image
    noise = DetectorNoise(outlier_rate=0.0, miss_rate=0.2, view_miss_rate=0.1)
    sim = simulate_detector(rig, X, np.random.default_rng(4), noise)
    conf, pixels = sim.points[..., 2], sim.points[..., :2]
    assert np.array_equal(conf == 0, sim.dropped) and np.isnan(pixels[sim.dropped]).all()
    assert np.isfinite(pixels[~sim.dropped]).all() and (conf[~sim.dropped] > 0).all()
    assert sim.dropped[:5, :, KEYPOINT_INDEX["nose"]].all()
    whole = sim.dropped.all(axis=-1)  # a view missing in a frame
    assert 0.06 < whole.mean() < 0.14
    assert 0.18 < sim.dropped[~whole].mean() < 0.23  # a fifth missed (and the stray noses)
    # A view missing every point does not stop the others from triangulating.
    found = triangulate_keypoints(rig, sim.points, fix_swaps=False)  # (relabelling would move the labels)
    assert np.isfinite(found.points[..., 0]).mean() > 0.85 and not found.used[sim.dropped].any()
    # Confidences: inliers high, outliers lower and more spread (the Beta distributions of DetectorNoise).
    sim = simulate_detector(rig, X, np.random.default_rng(5), DetectorNoise(outlier_rate=0.3))
    inlier = sim.points[..., 2][~sim.outliers & ~sim.dropped]
    outlier = sim.points[..., 2][sim.outliers]
    assert inlier.mean() > 0.8 and (inlier >= 0.3).mean() > 0.99
    assert 0.3 < outlier.mean() < 0.5 and outlier.std() > inlier.std()


def test_a_sequences_simulated_keypoints_record_the_detector_and_round_trip(tmp_path):
    model, q = poses(10)
    rig = default_rig(2)
    seq = SimpleNamespace(rig=rig, model=model, groundtruth=SimpleNamespace(poses=q), root=tmp_path)
    noise = DetectorNoise(noise_mm=10.0)
    keypoints = simulate_sequence_keypoints(seq, np.random.default_rng(0), noise)
    assert keypoints.points.shape == (10, 2, len(KEYPOINTS), 3) and keypoints.cameras == ("cam0", "cam1")
    assert keypoints.source["detector"] == "simulated" and keypoints.source["noise"]["noise_mm"] == 10.0
    assert keypoints.source["noise"]["inlier_confidence"] == list(noise.inlier_confidence)
    write_keypoints(tmp_path, keypoints)
    back = read_keypoints(tmp_path, ("cam0", "cam1"), 10)
    assert np.array_equal(back.points, keypoints.points, equal_nan=True) and back.source == keypoints.source
    with pytest.raises(InputError, match="ground-truth"):
        simulate_sequence_keypoints(SimpleNamespace(rig=rig, model=model, groundtruth=None), np.random.default_rng(0))
    for bad in (dict(outlier_rate=1.5), dict(noise_mm=-1.0), dict(outlier_confidence=(0.0, 1.0))):
        with pytest.raises(InputError):
            DetectorNoise(**bad)


def test_the_default_error_bound_follows_the_image_height():
    assert default_max_error_px(default_rig(2, 640, 480)) == pytest.approx(15.0 * 480 / 1080)
    assert default_max_error_px(default_rig(2, 480, 272)) == pytest.approx(15.0 * 272 / 1080)


def test_the_temporal_median_ignores_a_stray_frame_and_missing_values():
    t = np.arange(12, dtype=float)
    points = np.stack([t, 2 * t, np.zeros(12)], axis=-1)[:, None, :]  # T x 1 x 3, a straight line
    spoiled = points.copy()
    spoiled[5] += 500.0  # one stray frame
    out = median_filter(spoiled)
    assert out.shape == points.shape and np.abs(out - points).max() <= 2.0  # within a frame's step of the line
    assert np.allclose(out[0], np.median(points[:3], axis=0))  # a shorter window at the ends
    spoiled[8] = np.nan  # one missing: stays missing unless filled, and the rest stay near the line
    out = median_filter(spoiled)
    assert np.isnan(out[8]).all() and np.nanmax(np.abs(out - points)) <= 2.0
    assert np.allclose(median_filter(spoiled, fill=True)[8], np.median(points[[6, 7, 9, 10]], axis=0))
    assert np.array_equal(median_filter(points, window=1), points)
    with pytest.raises(InputError):
        median_filter(points, window=4)


def test_triangulated_keypoints_written_as_a_trc(tmp_path):
    assert len(TRC_NAMES) == len(KEYPOINTS) and TRC_NAMES[:5] == ("Nose", "LEar", "REar", "Neck", "Head")
    X = truth(4)
    X[1, 0] = np.nan
    path = write_keypoints_trc(tmp_path / "keypoints.trc", X, fps=30.0)
    back = read_trc(path)
    assert back.names == list(TRC_NAMES) and back.fps == 30.0
    assert np.isnan(back.points[1, 0]).all()
    assert np.allclose(back.points[np.isfinite(X)], X[np.isfinite(X)], atol=1e-3)
