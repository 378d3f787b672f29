"""The start from keypoints: the body measured from triangulated keypoints and the first poses fitted to them,
with four views and with one, on a synthetic walk whose keypoints come from the detector noise model."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from data_tools.sequences.keypoint_file import write_keypoints
from data_tools.sequences.sequence import read_sequence
from data_tools.vision.keypoints.simulate import simulate_sequence_keypoints
from tracker.app.keypoint_start import initialise_from_keypoints, keypoint_lengths
from tracker.core.errors import InputError
from tracker.core.keypoint_fit import fit_pose
from tracker.core.keypoints import KEYPOINTS, keypoint_positions
from tracker.core.kinematics import markers

LIMBS = slice(3, 15)  # the markers of the 12 limb joints


@pytest.fixture(scope="module")
def walk_with_keypoints(walk_32_frames, tmp_path_factory):
    """A copy of the synthetic walk with simulated detections (seeded) in keypoints/."""
    root = tmp_path_factory.mktemp("keypoint_start") / "walk"
    shutil.copytree(walk_32_frames.root, root)
    write_keypoints(root, simulate_sequence_keypoints(read_sequence(root), np.random.default_rng(5)))
    return read_sequence(root)


def heading_error(found: np.ndarray, truth: np.ndarray) -> float:
    """Degrees between two poses' headings (their root orientations' turn about +z)."""
    from tracker.core.rotations import exp_map_to_matrix

    forward = [exp_map_to_matrix(p[3:6])[:, 0] for p in (found, truth)]
    angles = [np.arctan2(f[1], f[0]) for f in forward]
    return float(np.degrees(abs(np.angle(np.exp(1j * (angles[0] - angles[1]))))))


@pytest.mark.slow
def test_four_views_measure_the_body_and_start_on_the_person(walk_with_keypoints):
    seq = walk_with_keypoints
    start = initialise_from_keypoints(seq, known_frames=2)
    truth = seq.groundtruth
    assert start.poses.shape == (2, seq.model.n_dofs)
    assert np.all(start.model.within_limits(start.poses))
    errors = np.linalg.norm(markers(start.model, start.poses) - truth.markers[:2], axis=-1)[:, LIMBS].mean(axis=1)
    assert np.all(errors < 50.0), errors  # mm, over the 12 limb joints
    assert heading_error(start.poses[0], truth.poses[0]) < 15.0
    true_points = keypoint_positions(seq.model, truth.poses[:10])
    for name, value in keypoint_lengths(true_points).items():
        assert start.lengths[name] == pytest.approx(value, rel=0.1), name


@pytest.mark.slow
def test_one_view_starts_facing_the_right_way(walk_with_keypoints):
    seq = walk_with_keypoints
    start = initialise_from_keypoints(seq, views=[1], known_frames=2)
    assert start.lengths == {}  # nothing measured with one view
    assert heading_error(start.poses[0], seq.groundtruth.poses[0]) < 45.0
    found = markers(start.model, start.poses[0])[LIMBS]
    found -= found.mean(axis=0)
    truth = seq.groundtruth.markers[0][LIMBS]
    truth -= truth.mean(axis=0)
    assert np.linalg.norm(found - truth, axis=-1).mean() < 80.0  # mm, the depth left out


@pytest.mark.slow
def test_the_fit_keeps_joint_limits_and_finds_a_known_pose(walk_with_keypoints):
    seq = walk_with_keypoints
    truth = seq.groundtruth.poses[5]
    pixels, _ = seq.rig.project(keypoint_positions(seq.model, truth))
    exact = np.concatenate([pixels, np.ones(pixels.shape[:-1] + (1,))], axis=-1)
    start = truth.copy()
    start[6:] = 0.0  # every joint at rest, the root known
    fitted = fit_pose(seq.model, seq.rig, exact, start[None], iterations=300)
    assert np.all(seq.model.within_limits(fitted.poses))
    found = markers(seq.model, fitted.pose)
    assert np.linalg.norm(found - markers(seq.model, truth), axis=-1)[LIMBS].mean() < 15.0


def test_lengths_of_keypoints_no_view_pair_sees_are_refused():
    nothing = np.full((3, len(KEYPOINTS), 3), np.nan)
    with pytest.raises(InputError, match="upper arm"):
        keypoint_lengths(nothing)
