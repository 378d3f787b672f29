"""Replaying a pose clip at another speed (tracker.core.timewarp): slerped rotations, interpolated positions."""

import numpy as np
import pytest

from tracker.core.body import fifteen_cone_model
from tracker.core.errors import InputError
from tracker.core.rotations import exp_map_to_matrix
from tracker.core.timewarp import exp_map_triples, parse_speeds, time_warp_clip, warped_length

MODEL = fifteen_cone_model()
TRIPLES = exp_map_triples(MODEL)


def _random_clip(rng, T=40):
    """A smooth clip: every pose number a random walk with small steps from the rest pose."""
    steps = rng.normal(0, 0.02, (T, MODEL.n_dofs))
    steps[:, :3] = rng.normal(0, 10, (T, 3))
    return MODEL.rest_pose() + np.cumsum(steps, axis=0)


def _angle_between(Ra, Rb):
    cos = (np.trace(np.swapaxes(Ra, -1, -2) @ Rb, axis1=-2, axis2=-1) - 1) / 2
    return np.arccos(np.clip(cos, -1, 1))


def test_the_exp_maps_are_the_root_orientation_and_the_ball_joints():
    names = [MODEL.dof_names[i] for t in TRIPLES for i in t]
    assert len(TRIPLES) == 7 and names[:3] == ["root_rx", "root_ry", "root_rz"]
    assert {n.rsplit("_", 1)[0] for n in names[3:]} == {"left_hip", "right_hip", "left_shoulder", "right_shoulder",
                                                         "head", "abdomen"}


def test_speed_one_reproduces_the_clip_exactly():
    clip = _random_clip(np.random.default_rng(0))
    out = time_warp_clip(clip, 1.0, TRIPLES)
    assert np.array_equal(out, clip) and out is not clip


def test_half_speed_halves_a_constant_velocity_step_and_doubles_the_length():
    T = 30
    clip = np.tile(MODEL.rest_pose(), (T, 1))
    clip[:, 0] = 12.0 * np.arange(T)  # 12 mm per frame along x
    clip[:, 1] = -4.0 * np.arange(T)
    out = time_warp_clip(clip, 0.5, TRIPLES)
    assert len(out) == 2 * T - 1 == warped_length(T, 0.5)
    assert np.allclose(np.diff(out[:, 0]), 6.0) and np.allclose(np.diff(out[:, 1]), -2.0)
    assert np.array_equal(out[::2], clip)  # the original frames are kept exactly
    fast = time_warp_clip(clip, 2.0, TRIPLES)
    assert len(fast) == (T - 1) // 2 + 1 and np.allclose(np.diff(fast[:, 0]), 24.0)


def test_rotations_are_slerped_and_stay_on_the_continuous_branch_across_pi():
    T = 12
    clip = np.tile(MODEL.rest_pose(), (T, 1))
    heading = np.linspace(2.9, 3.45, T)  # the root turns about the vertical through pi: exp maps past norm pi
    clip[:, 5] = heading
    out = time_warp_clip(clip, 0.5, TRIPLES)
    mid = (heading[:-1] + heading[1:]) / 2
    assert np.allclose(out[1::2, 5], mid, atol=1e-9) and np.allclose(out[:, 3:5], 0, atol=1e-9)
    assert np.max(np.abs(np.diff(out[:, 3:6], axis=0))) < 0.03  # no jump of 2 pi anywhere
    assert np.all(np.linalg.norm(out[1::2, 3:6], axis=1)[mid > np.pi] > np.pi)


def test_a_ball_joint_midpoint_is_the_geodesic_midpoint():
    rng = np.random.default_rng(3)
    T = 6
    clip = np.tile(MODEL.rest_pose(), (T, 1))
    hip = list(TRIPLES[1])
    clip[:, hip] = rng.normal(0, 0.8, (T, 3))  # rotations far apart from frame to frame
    out = time_warp_clip(clip, 0.5, TRIPLES)
    R0, R1 = exp_map_to_matrix(clip[:-1, hip]), exp_map_to_matrix(clip[1:, hip])
    Rm = exp_map_to_matrix(out[1::2, hip])
    assert np.allclose(_angle_between(R0, Rm), _angle_between(Rm, R1), atol=1e-7)
    assert np.allclose(_angle_between(R0, Rm), _angle_between(R0, R1) / 2, atol=1e-7)
    # Averaging the exp-map components would not give the geodesic midpoint here.
    lin = exp_map_to_matrix((clip[:-1, hip] + clip[1:, hip]) / 2)
    assert np.max(np.abs(_angle_between(R0, lin) - _angle_between(lin, R1))) > 1e-3


@pytest.mark.parametrize("bad", ["", "0", "-1", "nan", "inf", "1e9", "0.05", "11", "fast", "1,,2"])
def test_bad_speeds_are_refused_naming_the_option_and_the_range(bad):
    with pytest.raises(InputError, match=r"time_warp must be comma-separated playback speeds, each in \[0.1, 10\]"):
        parse_speeds(bad)


def test_speeds_are_parsed_in_order_without_duplicates():
    assert parse_speeds("0.6, 0.8,1,1.25,1") == (0.6, 0.8, 1.0, 1.25)
    assert parse_speeds([0.5, 2]) == (0.5, 2.0) and parse_speeds("[0.7, 1]") == (0.7, 1.0)
