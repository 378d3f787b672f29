import numpy as np
import pytest

from tracker.core.body import (
    DOF_NAMES, MARKER_NAMES, SEGMENT_NAMES, BodyShape, default_shape, fifteen_cone_model,
)
from tracker.core.errors import InputError
from tracker.core.kinematics import forward_kinematics, markers, point_jacobians, standing_height


@pytest.fixture(scope="module")
def model():
    return fifteen_cone_model()


def marker(model, q, name):
    return markers(model, q)[..., MARKER_NAMES.index(name), :]


def test_pose_layout_matches_design(model):
    assert model.n_dofs == 40 and len(set(DOF_NAMES)) == 40
    assert len(SEGMENT_NAMES) == 15 and len(model.segments) == 15
    assert len(MARKER_NAMES) == 15
    blocks = {"root": 6, "left_hip": 3, "right_hip": 3, "left_shoulder": 3, "right_shoulder": 3, "head": 3,
              "abdomen": 3, "left_clavicle": 2, "right_clavicle": 2, "left_elbow": 2, "right_elbow": 2,
              "left_knee": 2, "right_knee": 2, "left_wrist": 1, "right_wrist": 1, "left_ankle": 1,
              "right_ankle": 1}
    for prefix, n in blocks.items():
        assert sum(d.startswith(prefix + "_") for d in DOF_NAMES) == n, prefix
    assert np.all(model.lower < model.upper)


def test_rest_pose_by_hand(model):
    s = default_shape()
    q = model.rest_pose()
    assert model.within_limits(q)
    m = markers(model, q)
    root = np.array([0, 0, model.rest_root_height])
    L = s.lengths
    expect = {
        "pelvis": root,
        "thorax": root + [0, 0, L["torso"]],
        "head": root + [0, 0, L["torso"] + L["head"]],
        "left_shoulder": root + [0, 0, L["torso"]] + s.left_shoulder_offset,
        "left_elbow": root + [0, 0, L["torso"] - L["left_upper_arm"]] + s.left_shoulder_offset,
        "right_wrist": root + [0, 0, L["torso"] - L["right_upper_arm"] - L["right_lower_arm"]]
        + s.right_shoulder_offset,
        "left_hip": root + s.left_hip_offset,
        "right_knee": root + s.right_hip_offset + [0, 0, -L["right_upper_leg"]],
        "left_ankle": root + s.left_hip_offset + [0, 0, -L["left_upper_leg"] - L["left_lower_leg"]],
    }
    for name, pos in expect.items():
        assert np.allclose(m[MARKER_NAMES.index(name)], pos, atol=1e-9), name
    # Left limbs on +y, feet on the floor, stature 1.75 m.
    assert m[MARKER_NAMES.index("left_hip"), 1] > 0 > m[MARKER_NAMES.index("right_hip"), 1]
    assert standing_height(model) == pytest.approx(1748.3, abs=1.0)


def test_single_joint_rotations(model):
    q = model.rest_pose()
    s = default_shape()
    # Elbow flexed 90 degrees: forearm points forward (+x) from the elbow.
    q1 = q.copy()
    q1[model.dof_index("left_elbow_flexion")] = np.pi / 2
    d = marker(model, q1, "left_wrist") - marker(model, q1, "left_elbow")
    assert np.allclose(d, [s.lengths["left_lower_arm"], 0, 0], atol=1e-9)
    # Knee flexed 90 degrees: shin points backward (-x).
    q2 = q.copy()
    q2[model.dof_index("right_knee_flexion")] = np.pi / 2
    d = marker(model, q2, "right_ankle") - marker(model, q2, "right_knee")
    assert np.allclose(d, [-s.lengths["right_lower_leg"], 0, 0], atol=1e-9)
    # Left shoulder abducted 90 degrees (exp map about +x): arm horizontal toward +y.
    q3 = q.copy()
    q3[model.dof_index("left_shoulder_x")] = np.pi / 2
    d = marker(model, q3, "left_elbow") - marker(model, q3, "left_shoulder")
    assert np.allclose(d, [0, s.lengths["left_upper_arm"], 0], atol=1e-9)
    # Hip flexion (exp map about -y) swings the thigh forward.
    q4 = q.copy()
    q4[model.dof_index("left_hip_y")] = -np.pi / 2
    d = marker(model, q4, "left_knee") - marker(model, q4, "left_hip")
    assert np.allclose(d, [s.lengths["left_upper_leg"], 0, 0], atol=1e-9)
    # Root yaw of 90 degrees turns the body to face +y; translation moves everything.
    q5 = q.copy()
    q5[5] = np.pi / 2
    q5[:2] = [100.0, -50.0]
    d = marker(model, q5, "left_hip") - marker(model, q5, "pelvis")
    assert np.allclose(d, [-s.left_hip_offset[1], 0, s.left_hip_offset[2]], atol=1e-9)
    assert np.allclose(marker(model, q5, "pelvis")[:2], [100, -50])


def test_limits(model):
    q = model.rest_pose()
    q[model.dof_index("left_elbow_flexion")] = np.radians(175)
    assert not model.within_limits(q)
    assert model.within_limits(model.clip_to_limits(q))
    batch = np.stack([model.rest_pose(), q])
    assert model.within_limits(batch).tolist() == [True, False]


def test_batched_equals_looped(model, rng):
    P = 64
    q = model.rest_pose() + np.concatenate([rng.normal(size=(P, 6)) * [100, 100, 10, .5, .5, .5],
                                            rng.normal(size=(P, 34)) * 0.4], axis=1)
    fk = forward_kinematics(model, q)
    for i in range(0, P, 9):
        one = forward_kinematics(model, q[i])
        assert np.allclose(one.points, fk.points[i], atol=1e-12)
        assert np.allclose(one.segment_frames(), fk.segment_frames()[i], atol=1e-12)
    assert fk.segment_frames().shape == (P, 15, 4, 4)
    assert forward_kinematics(model, q.reshape(8, 8, 40)).markers.shape == (8, 8, 15, 3)


def test_segment_frames_are_rigid_and_end_at_child_joints(model, rng):
    q = model.rest_pose() + rng.normal(size=(10, 40)) * 0.3
    fk = forward_kinematics(model, q)
    F = fk.segment_frames()
    R = F[..., :3, :3]
    assert np.allclose(R @ np.swapaxes(R, -1, -2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0)
    # The upper arm's distal end (along segment z) is the elbow.
    k = SEGMENT_NAMES.index("left_upper_arm")
    L = model.segments[k].length
    end = F[:, k, :3, 3] + L * F[:, k, :3, 2]
    assert np.allclose(end, fk.markers[:, MARKER_NAMES.index("left_elbow")], atol=1e-9)


def test_point_jacobians_match_finite_differences(model, rng):
    q = model.rest_pose() + rng.normal(size=(4, 40)) * 0.5
    J = point_jacobians(model, q)
    h = 1e-6
    Jn = np.stack([(forward_kinematics(model, q + h * e).points - forward_kinematics(model, q - h * e).points)
                   / (2 * h) for e in np.eye(40)], axis=-1)
    assert np.allclose(J, Jn, atol=1e-5)


def test_check_poses_rejects_bad_input(model):
    with pytest.raises(InputError, match=r"shape \(\.\.\., 40\)"):
        model.check_poses(np.zeros((3, 39)))
    bad = np.zeros((2, 40))
    bad[1, 7] = np.nan
    with pytest.raises(InputError, match="NaN"):
        model.check_poses(bad)


def test_shape_validation_and_round_trip():
    s = default_shape()
    assert BodyShape.from_json(s.to_json()).to_dict() == s.to_dict()
    d = s.to_dict()
    d["lengths"]["left_upper_arm"] = -3.0
    with pytest.raises(InputError, match="left_upper_arm"):
        BodyShape.from_dict(d, "subject.json")
    with pytest.raises(InputError, match="subject.json"):
        BodyShape.from_json("{", "subject.json")
