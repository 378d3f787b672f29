"""The ground-contact term (:mod:`likelihoods.ground_contact`): a pose whose feet or root leave their known
heights is penalised as declared, on by default with one camera and off with more, and a stopped run continues
to the same numbers."""
import numpy as np
import pytest

import tracker
from likelihoods.ground_contact import GroundContact, GroundContactConfig, lowest_foot_height
from tracker.core.body import fifteen_cone_model


@pytest.fixture(scope="module")
def model():
    return fifteen_cone_model()


def test_a_pose_lifted_by_d_loses_its_square_over_the_spreads(model):
    term = GroundContact(model, GroundContactConfig(ground_std=20.0, root_height_std=60.0))
    known = np.repeat(model.rest_pose()[None], 2, axis=0)
    term.start(known)
    lifted = np.repeat(model.rest_pose()[None], 4, axis=0)
    d = np.array([0.0, 10.0, -30.0, 100.0])
    lifted[:, model.links[0].dofs[2]] += d  # the whole body up or down: feet and root by d
    expected = -0.5 * (d / 20.0) ** 2 - 0.5 * (d / 60.0) ** 2
    assert np.allclose(term.log_likelihood(lifted), expected)
    assert np.allclose(lowest_foot_height(model, lifted) - lowest_foot_height(model, known[:1]), d)


def test_only_the_given_part_counts_and_not_finite_poses_get_nothing(model):
    term = GroundContact(model, GroundContactConfig(ground_std=20.0))
    poses = np.repeat(model.rest_pose()[None], 2, axis=0)
    poses[0, model.links[0].dofs[2]] += 40.0
    poses[1] = np.nan
    assert np.allclose(term.log_likelihood(poses), [-2.0, 0.0])
    assert not GroundContactConfig().active


def test_on_by_default_with_one_camera_off_with_more_and_either_as_given(small_walk):
    small_walk = tracker.load_sequence(small_walk)
    several = tracker.build_likelihood("edge-silhouette", small_walk)
    one = tracker.build_likelihood("edge-silhouette", small_walk, views=[0])
    assert several.name == "edge-silhouette" and one.name == "edge-silhouette+ground-contact"
    assert one.settings()["ground-contact"] == {"ground_std": 20.0, "root_height_std": 60.0}
    assert tracker.build_likelihood("edge-silhouette", small_walk, views=[0], ground_std=0.0,
                                    root_height_std=0.0).name == "edge-silhouette"
    grounded = tracker.build_likelihood("edge-silhouette", small_walk, ground_std=30.0)
    assert grounded.settings()["ground-contact"] == {"ground_std": 30.0, "root_height_std": 0.0}
    with_keypoints = tracker.build_likelihood("keypoints+edge-silhouette", small_walk, views=[0])
    assert "ground-contact" in with_keypoints.name


def test_a_stopped_run_with_ground_contact_continues_to_the_same_numbers(synthetic_walk, tmp_path):
    settings = dict(particles=40, annealing_layers=1, seed=5, checkpoint_every=1, views=[0], ground_std=20.0,
                    root_height_std=60.0)
    whole = tracker.track_into(tmp_path / "whole", synthetic_walk.root, "zero-velocity", **settings)
    count = {"n": 0}

    def stop(step, error):
        count["n"] += 1
        if count["n"] == 2:
            raise KeyboardInterrupt

    with pytest.raises(tracker.app.run_folder.TrackingStopped):
        tracker.track_into(tmp_path / "cut", synthetic_walk.root, "zero-velocity", on_frame=stop, **settings)
    resumed = tracker.resume_tracking(tmp_path / "cut")
    assert np.array_equal(resumed.poses, whole.poses)
    plain = tracker.track(synthetic_walk.root, "zero-velocity", **{**settings, "ground_std": 0.0,
                                                                   "root_height_std": 0.0})
    assert not np.array_equal(plain.poses, whole.poses)  # the term does move the particles


def test_one_camera_of_a_bodytrack_sequence_holds_the_ankles_of_its_ten_cone_body(bodytrack_dir):
    """PARSEC's 10-cone body has ankles and no toes: the term holds the lowest ankle."""
    sequence = tracker.load_sequence(bodytrack_dir)
    likelihood = tracker.build_likelihood("edge-silhouette", sequence, views=[0])
    assert likelihood.name == "edge-silhouette+ground-contact"
    term = likelihood.parts[1]
    model = term.model
    assert model.name != fifteen_cone_model().name and "left_toe" not in {p.name for p in model.points}
    poses = np.repeat(model.rest_pose()[None], 2, axis=0)
    term.start(poses)
    poses[1, model.links[0].dofs[2]] += 40.0
    assert np.allclose(term.log_likelihood(poses), [0.0, -0.5 * 2.0 ** 2 - 0.5 * (40.0 / 60.0) ** 2])
