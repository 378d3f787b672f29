"""The CRBM's height above standing (``train --standing-height``): root heights learned above each training
subject's standing root height and predicted above the tracked person's, so that one model fits people of
other sizes."""
import numpy as np
import pytest
import torch

from priors.crbm import CRBMConfig, CRBMPrior, heights_above_standing, load_crbm, train_crbm
from tracker.core.body import DOF_NAMES, fifteen_cone_model
from tracker.core.errors import InputError

#: Standing root height of the subject 07's body model (mm; ``fifteen_cone_model(shape).rest_root_height``).
STANDING_07 = 966.0


@pytest.fixture(scope="module")
def walk_07_01(mocap_dir):
    from data_tools.asf_amc import asf_amc_clip
    from data_tools.retarget import retarget

    torch.set_num_threads(1)
    return retarget(asf_amc_clip(mocap_dir / "07" / "07.asf", mocap_dir / "07" / "07_01.amc"), fps=60).poses


def _train(walk, standing: bool) -> object:
    cfg = CRBMConfig(order=2, hidden=60, epochs=120, standing_height=standing)
    return train_crbm([walk], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(4),
                      standing_heights=[STANDING_07] if standing else None)


@pytest.fixture(scope="module")
def standing(walk_07_01):
    return _train(walk_07_01, True)


@pytest.fixture(scope="module")
def absolute(walk_07_01):
    return _train(walk_07_01, False)


def _rolled_out_height_error(prior: CRBMPrior, walk: np.ndarray) -> float:
    """Mean sampled root height minus the walk's (mm) after 30 frames rolled out from its frames 58-59."""
    rng = np.random.default_rng(2)
    history = np.repeat(walk[None, 58:60], 50, axis=0)
    state = prior.start(walk[:60], 50, rng)
    for _ in range(30):
        poses, state = prior.sample(history, 2, state, rng)
        history = np.concatenate([history[:, 1:], poses[:, None]], axis=1)
    return float(np.mean(history[:, -1, 2]) - walk[89, 2])


def test_the_model_learns_heights_below_standing_not_above_the_floor(standing, absolute, walk_07_01):
    # The walk's root is 0-60 mm below subject 7's standing root height, ~950 mm above the floor.
    assert -60 < standing.normaliser.mean[2] < 0
    assert absolute.normaliser.mean[2] == pytest.approx(standing.normaliser.mean[2] + STANDING_07, abs=1e-6)
    assert "heights above standing" in standing.summary() and "standing" not in absolute.summary()


def test_a_shorter_person_keeps_their_own_height(standing, absolute, walk_07_01):
    """The same walk 100 mm lower, by a person whose standing root height is 100 mm lower: the model of heights
    above standing follows the person's height; the model of absolute heights pulls the root back up toward
    subject 7's."""
    lowered = walk_07_01.copy()
    lowered[:, 2] -= 100.0
    own = _rolled_out_height_error(CRBMPrior([standing], standing_root_height=STANDING_07 - 100.0), lowered)
    learned = _rolled_out_height_error(CRBMPrior([absolute]), lowered)
    assert abs(own) < 25 and learned > 50, (own, learned)


def test_the_model_file_keeps_the_height_reference(standing, absolute, tmp_path):
    standing.growth = [absolute]
    try:
        path = tmp_path / "m.pt"
        standing.save(path)
        with pytest.raises(InputError, match="height reference") as err:  # growth models must agree
            load_crbm(path)
        assert str(path) in str(err.value)
    finally:
        standing.growth = []
    standing.save(path)
    assert load_crbm(path).standing_height and not load_crbm(path).growth
    absolute.save(path)  # written without the key, as files from before the setting existed
    assert "standing_height" not in torch.load(path, weights_only=True)["config"]
    assert not load_crbm(path).standing_height


def test_standing_height_settings_that_cannot_work_are_refused(standing, absolute, tmp_path):
    with pytest.raises(InputError, match="needs it"):
        CRBMPrior([standing])  # no standing height of the tracked person
    with pytest.raises(InputError, match="relative height"):
        CRBMPrior([standing], standing_root_height=900.0, relative_height=True)
    with pytest.raises(InputError, match="heights above standing or none"):
        CRBMPrior([absolute, _train_order_1(standing)], standing_root_height=900.0)
    with pytest.raises(InputError, match="standing root height"):
        heights_above_standing([np.zeros((5, 40))], None)
    with pytest.raises(InputError, match="positive"):
        heights_above_standing([np.zeros((5, 40))], [-3.0])
    from priors.deep_crbm import load_deep_crbm

    path = tmp_path / "deep.pt"
    torch.save({"format": "pose-tracker deep-crbm v1", "bottom": standing.to_document()}, path)
    with pytest.raises(InputError, match="heights above standing"):
        load_deep_crbm(path)


def _train_order_1(like) -> object:
    """A tiny order-1 model of heights above standing (another order than ``like``, to combine with it)."""
    walk = np.zeros((20, 40))
    walk[:, 2] = 900.0 + np.arange(20.0)
    walk[:, 0] = 10.0 * np.arange(20.0)
    return train_crbm([walk], CRBMConfig(order=1, hidden=5, epochs=1, standing_height=True), 60.0, DOF_NAMES,
                      rng=np.random.default_rng(0), standing_heights=[950.0])


def test_training_data_carries_each_clips_standing_height_through_the_time_warp(walk_07_01):
    from tracker.engine.registry import TrainingData

    data = TrainingData((walk_07_01, walk_07_01[:200]), 60.0, fifteen_cone_model(), ("a", "b"),
                        standing_heights=(966.0, 880.0)).time_warped("0.8,1")
    assert data.standing_heights == (966.0, 966.0, 880.0, 880.0)


def test_train_reads_each_subjects_standing_height_from_its_skeleton(mocap_dir):
    """Through the API, with ``standing_height=True``, clips of two subjects of different sizes (7: 966 mm
    standing root height, 91: 880 mm) give one model whose mean height is below standing, where the absolute
    heights differ by about 80 mm; by default the model keeps the absolute heights."""
    from tracker.app import api

    clips = [mocap_dir / "07" / "07_01.amc", mocap_dir / "91" / "91_straight_walk.amc"]
    model = api.train("crbm", clips, epochs=1, hidden=10, grow_from="none", pace_input=False, standing_height=True,
                      rng=0)
    assert model.standing_height and -40 < model.normaliser.mean[2] < 0
    model = api.train("crbm", clips, epochs=1, hidden=10, grow_from="none", pace_input=False, rng=0)
    assert not model.standing_height and 850 < model.normaliser.mean[2] < 1000
