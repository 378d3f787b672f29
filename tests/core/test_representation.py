import numpy as np
import pytest

from tracker.core.errors import InputError
from tracker.core.kinematics import markers
from tracker.core.representation import (
    FeatureNormaliser, feature_names, invariant_to_poses, poses_to_invariant, start_of,
)
from tracker.core.rotations import exp_map_to_matrix, matrix_to_exp_map


def test_round_trip_on_real_clip(walk_07_01, tmp_path):
    q = walk_07_01.poses
    f = poses_to_invariant(q)
    norm = FeatureNormaliser.fit(f, feature_names(walk_07_01.model.dof_names))
    norm.save(tmp_path / "stats.npz")
    norm = FeatureNormaliser.load(tmp_path / "stats.npz")
    xy, yaw = start_of(q)
    back = invariant_to_poses(norm.inverse(norm.transform(f)), xy, yaw)
    assert np.abs(back - q).max() < 1e-6
    err = np.linalg.norm(markers(walk_07_01.model, back) - markers(walk_07_01.model, q), axis=-1)
    assert err.max() < 1e-6  # mm


def test_features_are_what_they_claim(walk_07_01):
    f = poses_to_invariant(walk_07_01.poses)
    # Forward walking at 60 Hz: about 1.4 m/s forward, little sideways, upright.
    assert 15 < np.median(f[:, 0]) < 30
    assert abs(np.median(f[:, 1])) < 5
    assert np.abs(f[:, 3]).max() < 0.5 and np.abs(f[:, 4]).max() < 0.5


def test_invariant_to_ground_plane_motion(walk_07_01):
    """Turning the whole clip about the vertical and sliding it on the floor changes nothing."""
    q = walk_07_01.poses.copy()
    a = 2.0
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    moved = q.copy()
    moved[:, :3] = q[:, :3] @ Rz.T + [1234.0, -567.0, 0.0]
    moved[:, 3:6] = matrix_to_exp_map(Rz @ exp_map_to_matrix(q[:, 3:6]))
    assert np.allclose(poses_to_invariant(moved), poses_to_invariant(q), atol=1e-9)


def test_batched_histories(walk_07_01):
    hist = np.stack([walk_07_01.poses[i:i + 6] for i in range(5)])  # P x N x 40
    f = poses_to_invariant(hist)
    assert f.shape == (5, 6, 40)
    assert np.allclose(f[2], poses_to_invariant(walk_07_01.poses[2:8]))
    xy, yaw = start_of(hist)
    assert np.allclose(invariant_to_poses(f, xy, yaw), hist, atol=1e-9)


def test_constant_dimensions_dropped():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(100, 8))
    X[:, 3] = 0.7
    n = FeatureNormaliser.fit(X, [f"d{i}" for i in range(8)])
    assert n.n_kept == 7 and "d3" not in n.kept_names
    z = n.transform(X)
    assert np.allclose(z.mean(0), 0) and np.allclose(z.std(0), 1)
    assert np.allclose(n.inverse(z), X)


def test_bad_input():
    with pytest.raises(InputError, match="at least 2 frames"):
        poses_to_invariant(np.zeros((1, 40)))
    with pytest.raises(InputError, match="expects 40"):
        FeatureNormaliser.fit(np.zeros((5, 40)) + np.arange(5)[:, None], [str(i) for i in range(40)]).transform(
            np.zeros((2, 39)))
