import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tracker.core.rotations import (
    continuous_exp_maps, euler_to_matrix, exp_map_to_matrix, matrix_to_exp_map, matrix_to_yaw_pitch_roll,
    yaw_pitch_roll_to_matrix,
)


def test_exp_map_matches_scipy(rng):
    v = rng.normal(size=(500, 3)) * 1.5
    assert np.allclose(exp_map_to_matrix(v), Rotation.from_rotvec(v).as_matrix(), atol=1e-13)


def test_exp_map_keeps_batch_shape(rng):
    v = rng.normal(size=(4, 5, 3))
    assert exp_map_to_matrix(v).shape == (4, 5, 3, 3)
    assert matrix_to_exp_map(exp_map_to_matrix(v)).shape == (4, 5, 3)


@pytest.mark.parametrize("scale", [1e-9, 1e-3, 1.0, np.pi - 1e-7])
def test_log_inverts_exp(rng, scale):
    axis = rng.normal(size=(50, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    v = axis * scale
    R = exp_map_to_matrix(v)
    v2 = matrix_to_exp_map(R)
    assert np.allclose(exp_map_to_matrix(v2), R, atol=1e-12)
    if scale < 3:
        assert np.allclose(v2, v, atol=1e-12)


def test_exp_map_at_zero_is_identity():
    assert np.array_equal(exp_map_to_matrix(np.zeros(3)), np.eye(3))
    assert np.array_equal(matrix_to_exp_map(np.eye(3)), np.zeros(3))


def test_yaw_pitch_roll_round_trip(rng):
    yaw, pitch, roll = rng.uniform(-3, 3, 200), rng.uniform(-1.5, 1.5, 200), rng.uniform(-3, 3, 200)
    R = yaw_pitch_roll_to_matrix(yaw, pitch, roll)
    y2, p2, r2 = matrix_to_yaw_pitch_roll(R)
    assert np.allclose(np.stack([y2, p2, r2]), np.stack([yaw, pitch, roll]), atol=1e-10)
    # Yaw is the heading of the forward (x) axis.
    fwd = R[:, :, 0]
    assert np.allclose(np.arctan2(fwd[:, 1], fwd[:, 0]), yaw, atol=1e-10)


def test_euler_is_product_in_listed_order(rng):
    a = rng.normal(size=(10, 3))
    assert np.allclose(euler_to_matrix(a, "zxy"), Rotation.from_euler("ZXY", a).as_matrix(), atol=1e-13)


def test_continuous_exp_maps_removes_wraps():
    # A steady turn about z through more than one revolution.
    angles = np.linspace(0, 4 * np.pi, 200)
    v = matrix_to_exp_map(exp_map_to_matrix(angles[:, None] * np.array([0, 0, 1.0])))
    assert np.abs(np.diff(v[:, 2])).max() > 1.0  # principal values jump
    c = continuous_exp_maps(v)
    assert np.allclose(c[:, 2], angles, atol=1e-9)
    assert np.allclose(exp_map_to_matrix(c), exp_map_to_matrix(v), atol=1e-12)
