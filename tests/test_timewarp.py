"""Pace augmentation: time-warping training clips (tracker.core.timewarp) and train's time_warp option."""
import subprocess
import sys

import numpy as np
import pytest
import torch

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


def test_crbm_and_fcrbm_train_on_warped_clips_and_record_the_speeds(tmp_path):
    import tracker
    from data_tools.samples import sample_walks
    from priors.crbm import load_crbm
    from priors.fcrbm import load_fcrbm

    asf, walks = sample_walks()
    model = tracker.train("crbm", [walks[0]], skeletons=[asf], order=2, epochs=2, hidden=8, rng=0,
                          time_warp="0.5,1,2")
    assert model.time_warp == [0.5, 1.0, 2.0] and [g.time_warp for g in model.growth] == [[0.5, 1.0, 2.0]]
    assert len(model.sources) == 3 and model.sources[0].endswith("07_01.amc @ 0.5x")
    assert "clips replayed at speeds 0.5, 1, 2" in model.summary()
    model.save(tmp_path / "c.pt")
    loaded = load_crbm(tmp_path / "c.pt")
    assert loaded.time_warp == [0.5, 1.0, 2.0] and loaded.summary() == model.summary()
    plain = tracker.train("crbm", [walks[0]], skeletons=[asf], order=1, epochs=2, hidden=8, rng=0, time_warp="1")
    assert plain.time_warp == [1.0] and "replayed" not in plain.summary() and len(plain.sources) == 1
    # The warped data is more data: the normaliser sees slower and faster steps than the clip has.
    assert model.normaliser.std[0] > plain.normaliser.std[0]

    fc = tracker.train("fcrbm", [walks[0], walks[1]], skeletons=[asf], labels="slow,fast", order=1, epochs=2,
                       hidden=8, factors=4, features=2, rng=0, time_warp="0.8,1.25")
    assert fc.clip_labels == ["slow", "slow", "fast", "fast"] and fc.time_warp == [0.8, 1.25]
    fc.save(tmp_path / "f.pt")
    assert load_fcrbm(tmp_path / "f.pt").time_warp == [0.8, 1.25]
    with pytest.raises(InputError, match="1 label"):  # labels are per given clip, not per warped copy
        tracker.train("fcrbm", [walks[0], walks[1]], skeletons=[asf], labels="walk", epochs=1, time_warp="0.8,1")


def test_a_model_file_with_a_bad_time_warp_is_refused(tmp_path):
    import tracker
    from data_tools.samples import sample_walks
    from priors.crbm import load_crbm

    asf, walks = sample_walks()
    doc = tracker.train("crbm", [walks[0]], skeletons=[asf], order=1, epochs=1, hidden=4, rng=0).to_document()
    for bad in ([0.0], [float("nan")], "fast", []):
        doc["time_warp"] = bad
        torch.save(doc, tmp_path / "bad.pt")
        with pytest.raises(InputError, match="time_warp"):
            load_crbm(tmp_path / "bad.pt")
    del doc["time_warp"]  # files from before the option: the clips as given
    torch.save(doc, tmp_path / "old.pt")
    assert load_crbm(tmp_path / "old.pt").time_warp == [1.0]


def test_every_learned_prior_takes_the_option_declared_once():
    from tracker.app.api import available_priors, prior_entry
    from tracker.engine.registry import TRAINING_DATA_OPTIONS

    learned = [n for n in available_priors() if prior_entry(n).train is not None]
    assert {"crbm", "gpdm", "fcrbm", "deep-crbm"} <= set(learned)
    for name in learned:
        options = [o for o in prior_entry(name).train_options if o.name == "time_warp"]
        assert options == [TRAINING_DATA_OPTIONS[0]], name


@pytest.mark.parametrize("bad", ["0", "-0.5", "nan", "1e9", "", "0.6,x"])
def test_the_cli_refuses_bad_speeds_with_exit_2(tmp_path, bad):
    from data_tools.samples import sample_walks

    asf, walks = sample_walks()
    r = subprocess.run([sys.executable, "-m", "tracker", "train", "--prior", "gpdm", "--mocap", str(walks[0]),
                        "--time-warp", bad, "--out", str(tmp_path / "m.pt")], capture_output=True, text=True)
    last = r.stderr.strip().splitlines()[-1]
    assert r.returncode == 2 and "time_warp must be comma-separated playback speeds, each in [0.1, 10]" in last
    assert "Traceback" not in r.stderr and not (tmp_path / "m.pt").exists()
