"""The keypoint likelihood: the contract every likelihood keeps (alone and summed with the edge-silhouette
likelihood), and what makes it robust: a wrong detection costs little, a swapped left/right pair is absorbed,
a keypoint not found adds nothing, and the true pose scores above poses beside it."""
from __future__ import annotations

import numpy as np
import pytest

from data_tools.vision.keypoints.simulate import DetectorNoise, simulate_detections
from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood
from likelihoods.keypoints import KeypointConfig, KeypointLikelihood
from tracker.core.keypoints import KEYPOINT_INDEX, keypoint_positions, swap_permutation
from tracker.engine.likelihood import SumOfLikelihoods
from tracker.testing import LikelihoodContract

from tests.likelihoods import test_likelihood_contract as edge_silhouette_contract

FRAME = 12


def exact_detections(seq, frame: int, confidence: float = 0.9) -> np.ndarray:
    """The true keypoints of ``frame`` projected into every view, ``V x K x 3``."""
    pixels, _ = seq.rig.project(keypoint_positions(seq.model, seq.groundtruth.poses[frame]))
    return np.concatenate([pixels, np.full(pixels.shape[:-1] + (1,), confidence)], axis=-1)


class TestKeypoints(LikelihoodContract):
    """Frame 12 of the synthetic walk with keypoints from the detector noise model (seeded)."""

    @pytest.fixture(autouse=True)
    def sequence(self, walk_32_frames):
        self.seq = walk_32_frames
        truth = keypoint_positions(self.seq.model, self.seq.groundtruth.poses[FRAME:FRAME + 1])
        self.detections = simulate_detections(self.seq.rig, truth, np.random.default_rng(3))[0]

    def make_likelihood(self):
        return KeypointLikelihood(self.seq.model, self.seq.rig)

    def make_frame(self):
        frame = self.seq.frame(FRAME, range(self.seq.n_views))
        return type(frame)(frame.index, frame.images, frame.masks, frame.backgrounds, self.detections)

    make_poses = edge_silhouette_contract.TestEdgeSilhouette.make_poses  # the same poses, frame 12


class TestKeypointsWithSilhouettes(TestKeypoints):
    """The keypoints and the edges and silhouettes, summed (the default for sequences with keypoints)."""

    def make_likelihood(self):
        return SumOfLikelihoods([KeypointLikelihood(self.seq.model, self.seq.rig),
                                 EdgeSilhouetteLikelihood(self.seq.model, self.seq.rig)])


@pytest.fixture
def walk(walk_32_frames):
    return walk_32_frames


def score(seq, detections, poses, **config):
    return KeypointLikelihood(seq.model, seq.rig, KeypointConfig(**config)).log_likelihood(poses, detections)


def test_the_true_pose_scores_above_poses_beside_it(walk):
    truth = walk.groundtruth.poses[FRAME]
    moved = np.tile(truth, (6, 1))
    moved[np.arange(6), np.arange(6) % 3] += np.repeat([40.0, -40.0], 3)
    scores = score(walk, exact_detections(walk, FRAME), np.vstack([truth, moved]))
    assert np.all(scores[0] > scores[1:] + 5.0), scores


def test_a_wrong_detection_costs_at_most_its_outlier_bound(walk):
    truth = walk.groundtruth.poses[FRAME][None]
    detections = exact_detections(walk, FRAME)
    wrong = detections.copy()
    wrong[0, KEYPOINT_INDEX["left_wrist"], :2] += 200.0  # 200 pixels off in one view
    config = KeypointConfig()
    drop = score(walk, detections, truth)[0] - score(walk, wrong, truth)[0]
    # the inlier term of a perfect hit, at most: log(w N(0) / u), the most a point can lose
    assert 0.0 < drop < 25.0, drop
    near = wrong.copy()
    near[0, KEYPOINT_INDEX["left_wrist"], :2] = detections[0, KEYPOINT_INDEX["left_wrist"], :2] + 2000.0
    assert score(walk, near, truth)[0] == pytest.approx(score(walk, wrong, truth)[0], abs=1e-6), \
        "beyond the inliers' reach every wrong detection costs the same"
    assert config.outliers > 0


def test_a_swapped_limb_pair_is_absorbed(walk):
    truth = walk.groundtruth.poses[FRAME][None]
    detections = exact_detections(walk, FRAME)
    swapped = detections.copy()
    swapped[1] = detections[1][swap_permutation((0,))]  # view 1 labels the arms the wrong way round
    with_swaps = score(walk, detections, truth)[0] - score(walk, swapped, truth)[0]
    without = score(walk, detections, truth, swap=0.0)[0] - score(walk, swapped, truth, swap=0.0)[0]
    assert with_swaps == pytest.approx(np.log(0.95 / 0.05), abs=0.5), with_swaps
    assert without > 3 * with_swaps


def test_keypoints_not_found_add_nothing(walk):
    poses = walk.groundtruth.poses[FRAME] + np.random.default_rng(0).normal(0.0, 0.02, (5, walk.model.n_dofs))
    poses = walk.model.clip_to_limits(poses)
    detections = exact_detections(walk, FRAME)
    gone = detections.copy()
    gone[:, KEYPOINT_INDEX["nose"]] = (np.nan, np.nan, 0.0)
    without_nose = detections.copy()
    without_nose[:, KEYPOINT_INDEX["nose"], 2] = 0.0
    assert np.allclose(score(walk, gone, poses), score(walk, without_nose, poses))
    assert np.all(np.isfinite(score(walk, gone, poses)))


def test_confidence_weighs_a_detection(walk):
    truth = walk.groundtruth.poses[FRAME][None]
    high, low = exact_detections(walk, FRAME, 0.95), exact_detections(walk, FRAME, 0.4)
    for det in (high, low):
        det[2, KEYPOINT_INDEX["right_knee"], :2] += 150.0
    truth_high, truth_low = score(walk, exact_detections(walk, FRAME, 0.95), truth), score(
        walk, exact_detections(walk, FRAME, 0.4), truth)
    assert (truth_high - score(walk, high, truth))[0] > (truth_low - score(walk, low, truth))[0]


def test_refining_moves_proposals_towards_the_keypoints_within_the_limits(walk):
    from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood
    from tracker.core.kinematics import markers
    from tracker.engine.likelihood import RefiningFrameLikelihood

    truth = walk.groundtruth.poses[FRAME]
    rng = np.random.default_rng(2)
    scale = np.r_[[60.0] * 3, [0.15] * (truth.size - 3)]
    proposals = walk.model.clip_to_limits(truth + rng.standard_normal((200, truth.size)) * scale)
    detections = simulate_detections(walk.rig, keypoint_positions(walk.model, truth[None]), rng)[0]
    likelihood = KeypointLikelihood(walk.model, walk.rig)
    frame = walk.frame(FRAME, range(walk.n_views))
    frame = type(frame)(frame.index, frame.images, frame.masks, frame.backgrounds, detections)
    prepared = likelihood.prepare(frame)
    assert isinstance(prepared, RefiningFrameLikelihood)
    refined = prepared.refine(proposals)
    assert np.all(walk.model.within_limits(refined))

    def error(poses):
        return np.linalg.norm(markers(walk.model, poses) - walk.groundtruth.markers[FRAME], axis=-1)[:, 3:15].mean()

    assert error(refined) < 0.7 * error(proposals), (error(refined), error(proposals))
    assert np.mean(prepared(refined)) > np.mean(prepared(proposals))
    summed = SumOfLikelihoods([likelihood, EdgeSilhouetteLikelihood(walk.model, walk.rig)]).prepare(frame)
    assert isinstance(summed, RefiningFrameLikelihood)
    assert np.array_equal(summed.refine(proposals), refined)
    still = KeypointLikelihood(walk.model, walk.rig, KeypointConfig(refine_steps=0)).prepare(frame)
    assert not isinstance(still, RefiningFrameLikelihood)


def test_silhouettes_beside_keypoints_refuse_a_frame_without_masks_or_plates(walk):
    """A sequence with keypoints hands out frames without silhouettes: the silhouette part refuses in one line."""
    from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood
    from tracker.core.errors import InputError

    frame = walk.frame(FRAME, range(walk.n_views))
    bare = type(frame)(frame.index, frame.images, None, None, exact_detections(walk, FRAME))
    summed = SumOfLikelihoods([KeypointLikelihood(walk.model, walk.rig),
                               EdgeSilhouetteLikelihood(walk.model, walk.rig)])
    with pytest.raises(InputError, match="silhouettes SEQ"):
        summed.prepare(bare)
    KeypointLikelihood(walk.model, walk.rig).prepare(bare)  # the keypoints alone need neither
