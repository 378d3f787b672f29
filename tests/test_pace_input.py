"""The CRBM's pace input (``train --pace-input``): the pace label of training frames, a model whose gait speed
follows the pace it is given, the per-particle pace while tracking, and the model file's checks."""
import numpy as np
import pytest
import torch

from priors.crbm import CRBMConfig, CRBMPrior, PACED_DRIFT, PACED_JUMP, PACED_SPREAD, load_crbm, train_crbm
from tracker.core.body import DOF_NAMES, fifteen_cone_model
from tracker.core.errors import InputError
from tracker.core.representation import PACE_FLOOR_MM, clip_log_pace, poses_to_invariant
from tracker.core.timewarp import exp_map_triples, time_warp_clip

TRIPLES = exp_map_triples(fifteen_cone_model())


@pytest.fixture(scope="module")
def walk_07_01(mocap_dir):
    from data_tools.asf_amc import asf_amc_clip
    from data_tools.retarget import retarget

    torch.set_num_threads(1)
    return retarget(asf_amc_clip(mocap_dir / "07" / "07.asf", mocap_dir / "07" / "07_01.amc"), fps=60).poses


@pytest.fixture(scope="module")
def paced(walk_07_01):
    """A paced CRBM-3 (with its order-1 growth model) on 07_01 replayed at speeds 0.5, 1 and 1.5."""
    clips = [time_warp_clip(walk_07_01, s, TRIPLES) for s in (0.5, 1.0, 1.5)]
    cfg = CRBMConfig(order=3, hidden=100, epochs=150, pace_input=True)
    rng = np.random.default_rng(3)
    model = train_crbm(clips, cfg, 60.0, DOF_NAMES, rng=rng)
    model.growth = [train_crbm(clips, CRBMConfig(order=1, hidden=100, epochs=150, pace_input=True), 60.0,
                               DOF_NAMES, rng=rng)]
    return model


@pytest.fixture(scope="module")
def plain(walk_07_01):
    """A small order-1 CRBM without the pace input (a model file of the kind trained before it existed)."""
    return train_crbm([walk_07_01], CRBMConfig(order=1, hidden=20, epochs=2), 60.0, DOF_NAMES,
                      rng=np.random.default_rng(0))


def test_the_pace_label_is_the_log_of_the_smoothed_ground_speed(walk_07_01):
    pace = clip_log_pace(walk_07_01, 60)
    slow = clip_log_pace(time_warp_clip(walk_07_01, 0.5, TRIPLES), 60)
    feats = poses_to_invariant(walk_07_01)[:-1]
    speed = np.hypot(feats[:, 0], feats[:, 1])
    assert pace.shape == (len(walk_07_01) - 1,)
    assert np.exp(pace[80]) - PACE_FLOOR_MM == pytest.approx(speed[50:111].mean())  # centred window of 61 frames
    # Half the playback speed, half the ground speed (the middles of both clips: the same part of the walk).
    ratio = (np.exp(slow[len(slow) // 2]) - PACE_FLOOR_MM) / (np.exp(pace[len(pace) // 2]) - PACE_FLOOR_MM)
    assert ratio == pytest.approx(0.5, abs=0.05)
    standing = np.repeat(walk_07_01[:1], 20, axis=0)
    assert np.allclose(clip_log_pace(standing, 60), np.log(PACE_FLOOR_MM))  # finite for a person standing still


def test_the_model_walks_at_the_pace_it_is_given(paced, walk_07_01):
    """Rolled out for 90 frames from the same real history, the ground speed follows the pace input: the
    slower the pace given, the slower the walk, whatever the history's own speed."""
    prior = CRBMPrior([paced], gibbs_steps=5, pace_spread=0.0, pace_drift=0.0, pace_jump=0.0, root_noise_mm=0.0)
    rng = np.random.default_rng(0)
    speeds = []
    for mm_per_frame in (8.0, 16.0, 24.0):
        history = np.repeat(walk_07_01[None, 57:60], 20, axis=0)
        state = prior.start(walk_07_01[:60], 20, rng)
        state["pace"][:] = np.log(PACE_FLOOR_MM + mm_per_frame)
        for _ in range(90):
            poses, state = prior.sample(history, 3, state, rng)
            history = np.concatenate([history[:, 1:], poses[:, None]], axis=1)
        speeds.append(np.mean(np.hypot(*(history[:, -1, :2] - walk_07_01[59, :2]).T)) / 90)
    assert speeds[1] > 1.15 * speeds[0] and speeds[2] > 1.15 * speeds[1], speeds  # mm/frame


def test_each_particle_starts_at_the_known_pace_and_drifts(paced, walk_07_01):
    prior = CRBMPrior([paced])
    assert (prior.pace_spread, prior.pace_drift) == (PACED_SPREAD, PACED_DRIFT)
    rng = np.random.default_rng(1)
    state = prior.start(walk_07_01[:60], 4000, rng)
    step = poses_to_invariant(walk_07_01[58:60])[-1]
    known = np.log(PACE_FLOOR_MM + np.hypot(step[0], step[1]))
    assert np.mean(state["pace"]) == pytest.approx(known, abs=0.02)
    assert np.std(state["pace"]) == pytest.approx(PACED_SPREAD, rel=0.05)
    assert np.all(state["log_pace"] == 0)  # a paced model's ground steps are its own, never rescaled
    history = np.repeat(walk_07_01[None, 57:60], 4000, axis=0)
    _, after = prior.sample(history, 3, state, rng)
    moved = after["pace"] - state["pace"]
    assert PACED_JUMP == 0 and np.std(moved) == pytest.approx(PACED_DRIFT, rel=0.05)  # no jumps by default
    weights = np.full(4000, 1 / 4000)
    assert prior.summarize(after, weights)[0] == pytest.approx(np.mean(np.exp(after["pace"]) - PACE_FLOOR_MM))
    assert prior.summary_names == ("pace (mm/frame)", "height offset (mm)", "posture offset rms (deg)")  # by default


def test_a_paced_model_file_round_trips_and_samples_alike(paced, walk_07_01, tmp_path):
    path = tmp_path / "paced.pt"
    paced.save(path)
    loaded = load_crbm(path)
    assert loaded.pace_label == pytest.approx(paced.pace_label)
    assert [g.pace_label for g in loaded.growth] == [pytest.approx(paced.growth[0].pace_label)]
    history = np.repeat(walk_07_01[None, 57:60], 8, axis=0)
    draws = []
    for model in (paced, loaded):
        prior = CRBMPrior([model])
        rng = np.random.default_rng(5)
        draws.append(prior.sample(history, 3, prior.start(walk_07_01[:60], 8, rng), rng)[0])
    assert np.allclose(draws[0], draws[1], atol=1e-9)


def test_paced_model_files_are_checked(paced, plain, tmp_path):
    doc = paced.to_document()
    growth = plain.to_document()  # a valid order-1 model without the input
    for change, message in (({"pace_label": None}, "pace_label must be"),
                            ({"growth": [growth]}, "growth models and main model differ"),
                            ({"pace_label": [2.0, 0.0]}, "pace_label must be"),
                            ({"pace_label": [float("nan"), 0.3]}, "pace_label must be"),
                            ({"config": {**doc["config"], "pace_input": False}}, "not trained with a pace input")):
        path = tmp_path / "bad.pt"
        torch.save({**doc, **change}, path)
        with pytest.raises(InputError, match=message) as err:
            load_crbm(path)
        assert str(path) in str(err.value)


def test_paced_and_unpaced_models_do_not_mix(paced, plain):
    with pytest.raises(InputError, match="pace input or none"):
        CRBMPrior([plain, paced])
    assert CRBMPrior([plain]).pace_spread == 0.0  # the unpaced defaults are unchanged
    assert plain.to_document()["pace_label"] is None


def test_train_and_track_a_paced_model_from_the_command_line(mocap_dir, walk_32_frames, tmp_path):
    """``train --pace-input --time-warp`` writes a paced model file; ``track`` with it records the posterior mean
    pace per frame in result.json and draws it."""
    import json
    import subprocess
    import sys

    model = tmp_path / "paced.pt"
    r = subprocess.run([sys.executable, "-m", "tracker", "train", "--prior", "crbm", "--mocap",
                        str(mocap_dir / "07" / "07_01.amc"), "--order", "2", "--epochs", "5", "--hidden", "20",
                        "--pace-input", "--time-warp", "0.7,1", "--out", str(model)], capture_output=True, text=True)
    assert r.returncode == 0 and "paced" in r.stdout, r.stderr[-500:]
    out = tmp_path / "t"
    r = subprocess.run([sys.executable, "-m", "tracker", "track", str(walk_32_frames.root), "--prior", "crbm",
                        "--model", str(model), "--particles", "100", "--frames", "6", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-500:]
    result = json.loads((out / "result.json").read_text())
    summary = result["prior_summary"]
    assert summary["names"] == ["pace (mm/frame)", "height offset (mm)", "posture offset rms (deg)"]
    assert len(summary["per_frame"]) == result["frames"]
    assert all(0 < row[0] < 100 for row in summary["per_frame"])  # a walker's ground speed, mm per frame
    assert (out / "prior_summary.png").stat().st_size > 0


def height_error_on_a_lowered_walk(prior, walk: np.ndarray, particles: int, frames: int, seed: int,
                                   select_sd: float | None = None) -> float:
    """Rolls ``prior`` out from frame 60 of ``walk`` lowered by 100 mm (a shorter person) for ``frames`` frames with
    ``particles`` particles. With ``select_sd`` (mm) each frame's particles are weighted by how close their root
    height is to the person's and resampled (a stand-in for the likelihood). Returns the mean sampled root height
    of the last frame above the person's (mm)."""
    lowered = walk.copy()
    lowered[:, 2] -= 100.0
    rng = np.random.default_rng(seed)
    history = np.repeat(lowered[None, 57:60], particles, axis=0)
    state = prior.start(lowered[:60], particles, rng)
    for t in range(60, 60 + frames):
        poses, state = prior.sample(history, 3, state, rng)
        history = np.concatenate([history[:, 1:], poses[:, None]], axis=1)
        error = float(np.mean(poses[:, 2]) - lowered[t, 2])
        if select_sd is not None:
            w = np.exp(-0.5 * ((poses[:, 2] - lowered[t, 2]) / select_sd) ** 2) + 1e-300
            keep = rng.choice(particles, particles, p=w / w.sum())
            history, state = history[keep], {k: v[keep] for k, v in state.items()}
    return error


def test_relative_height_keeps_a_shorter_persons_own_height(paced, walk_07_01):
    """The same walk 100 mm lower (a shorter person): with ``relative_height`` the sampled root heights follow
    the person's, without it the model pulls them back up toward the training subject's."""
    errors = {relative: height_error_on_a_lowered_walk(
        CRBMPrior([paced], pace_spread=0.0, pace_drift=0.0, pace_jump=0.0, relative_height=relative),
        walk_07_01, particles=50, frames=30, seed=2) for relative in (False, True)}
    assert abs(errors[True]) < 25 and errors[False] > 50, errors


def test_a_particles_height_offset_moves_the_models_heights_by_exactly_that_offset(paced, walk_07_01):
    """A particle whose history and offset are both 70 mm higher samples the same pose 70 mm higher: the model
    sees the same input."""
    prior = CRBMPrior([paced], pace_spread=0.0, pace_drift=0.0, pace_jump=0.0, height_spread=30.0)
    history = np.repeat(walk_07_01[None, 57:60], 20, axis=0)
    raised = history.copy()
    raised[..., 2] += 70.0
    out = []
    for h, offset in ((history, 0.0), (raised, 70.0)):
        rng = np.random.default_rng(4)
        state = prior.start(walk_07_01[:60], 20, rng)
        state["height_offset"] = np.full(20, offset)
        poses, new = prior.sample(h, 3, state, rng)
        assert np.all(new["height_offset"] == offset)  # no drift: the offset keeps its value
        out.append(poses)
    assert np.allclose(out[1][:, 2] - out[0][:, 2], 70.0, atol=1e-6)
    assert np.allclose(np.delete(out[1], 2, axis=1), np.delete(out[0], 2, axis=1), atol=1e-6)


def test_height_offsets_start_spread_drift_and_are_summarised(paced, walk_07_01):
    rng = np.random.default_rng(5)
    prior = CRBMPrior([paced], height_spread=40.0, height_drift=2.0, posture_gain=0.0)
    assert prior.summary_names == ("pace (mm/frame)", "height offset (mm)")
    state = prior.start(walk_07_01[:60], 4000, rng)
    assert np.std(state["height_offset"]) == pytest.approx(40.0, rel=0.05)
    history = np.repeat(walk_07_01[None, 57:60], 4000, axis=0)
    _, new = prior.sample(history, 3, state, rng)
    assert np.std(new["height_offset"] - state["height_offset"]) == pytest.approx(2.0, rel=0.05)
    weights = np.zeros(4000)
    weights[:2] = 0.5
    summary = prior.summarize(new, weights)
    assert summary[1] == pytest.approx(np.mean(new["height_offset"][:2]))
    plain = CRBMPrior([paced], height_spread=0.0, posture_gain=0.0)
    assert "height_offset" not in plain.start(walk_07_01[:60], 10, rng) and len(plain.summary_names) == 1
    for bad in ({"height_spread": -1.0}, {"height_drift": float("nan")}):
        with pytest.raises(InputError, match="height"):
            CRBMPrior([paced], **bad)


def test_a_paced_crbm_gives_each_particle_a_height_offset_by_default(paced, plain, walk_07_01):
    from priors.crbm import PACED_HEIGHT_SPREAD
    from tracker.app.api import prior_entry

    assert PACED_HEIGHT_SPREAD == 50.0 and CRBMPrior([paced]).height_spread == PACED_HEIGHT_SPREAD
    assert CRBMPrior([plain]).height_spread == 0.0 and CRBMPrior([paced], height_spread=0.0).height_spread == 0.0
    option = {o.name: o for o in prior_entry("crbm").options}["height_spread"]
    assert option.default is None and "50 for a CRBM trained with a pace input" in option.help
    state = CRBMPrior([paced]).start(walk_07_01[:60], 4000, np.random.default_rng(8))
    assert np.std(state["height_offset"]) == pytest.approx(PACED_HEIGHT_SPREAD, rel=0.05)


def test_a_paced_crbm_corrects_its_posture_by_default(paced, plain):
    from priors.crbm import PACED_POSTURE_GAIN
    from tracker.app.api import prior_entry

    assert PACED_POSTURE_GAIN == 0.1 and CRBMPrior([paced]).posture_gain == PACED_POSTURE_GAIN
    assert CRBMPrior([plain]).posture_gain == 0.0 and CRBMPrior([paced], posture_gain=0.0).posture_gain == 0.0
    option = {o.name: o for o in prior_entry("crbm").options}["posture_gain"]
    assert option.default is None and f"{PACED_POSTURE_GAIN:g} for a CRBM trained with a pace input" in option.help
    deep = {o.name: o for o in prior_entry("deep-crbm").options}["posture_gain"]
    assert deep.default == 0.0


@pytest.mark.parametrize("option", ["height_spread", "posture_gain"])
def test_every_experiment_pins_the_defaults_its_crbms_ran_with(option):
    """A CRBM row made before a paced CRBM's height offsets (0.8.0) or posture correction (0.12.0) became the
    default keeps measuring as it did."""
    for f, prior in experiment_crbm_rows():
        assert option in prior.get("options", {}), (f.name, prior.get("label"), option)


def test_the_experiment_rows_that_name_a_posture_gain_are_the_only_ones_with_one():
    """Rows labelled "posture gain G" (rounds 23 and 24) track with G; every other CRBM row is pinned to 0."""
    import re

    for f, prior in experiment_crbm_rows():
        named = re.search(r"posture gain (\d+(?:\.\d+)?)", prior.get("label", ""))
        assert prior["options"]["posture_gain"] == (float(named.group(1)) if named else 0), (f.name, prior.get("label"))


def test_height_offsets_selected_by_the_images_follow_a_shorter_person(paced, walk_07_01):
    """The same walk 100 mm lower, each frame's particles weighted by how close their root height is to the
    person's (a stand-in for the likelihood) and resampled: with height offsets the sampled heights follow the
    person, without them the model keeps pulling the particles back up to the training subject's height."""
    errors = {spread: height_error_on_a_lowered_walk(
        CRBMPrior([paced], pace_spread=0.0, pace_drift=0.0, pace_jump=0.0, height_spread=spread),
        walk_07_01, particles=300, frames=40, seed=6, select_sd=20.0) for spread in (0.0, 60.0)}
    assert abs(errors[60.0]) < 25 and errors[0.0] > 40, errors


def test_by_default_a_pace_input_only_for_clips_of_several_paces(walk_07_01):
    from priors.crbm import given_clips, paces_vary
    from tracker.engine.registry import TrainingData

    assert not paces_vary([walk_07_01], 60.0)  # one walk: a 1% spread of paces
    assert paces_vary([walk_07_01, time_warp_clip(walk_07_01, 0.6, TRIPLES)], 60.0)
    # The default looks at the clips as given: --time-warp alone does not make a paced model.
    data = TrainingData((walk_07_01,), 60.0, fifteen_cone_model(), ("07_01.amc",)).time_warped("0.6,0.9,1.3")
    assert [len(c) for c in given_clips(data)] == [len(data.clips[1])]  # the copy at 0.9, nearest 1
    assert not paces_vary(given_clips(data), 60.0)


def experiment_crbm_rows():
    """Every ``[[prior]]`` entry named crbm in the experiment files, with its file."""
    import tomllib
    from pathlib import Path

    files = sorted((Path(__file__).parents[1] / "benchmarks" / "experiments").rglob("*.toml"))
    assert files
    for f in files:
        for prior in tomllib.loads(f.read_text()).get("prior", []):
            if prior.get("name") == "crbm":
                yield f, prior


def test_every_experiment_pins_the_pace_input_and_height_reference_of_its_crbms():
    """An experiment's CRBM rows keep measuring what their published table measured whatever train's defaults."""
    for f, prior in experiment_crbm_rows():
        for entry in prior.get("train", []):
            for option in ("pace_input", "standing_height"):
                assert option in entry.get("options", {}), (f.name, prior.get("label"), option)


def test_a_deep_crbm_file_with_a_paced_first_layer_is_refused(paced, tmp_path):
    from priors.deep_crbm import load_deep_crbm

    path = tmp_path / "deep.pt"
    torch.save({"format": "pose-tracker deep-crbm v1", "bottom": paced.to_document()}, path)
    with pytest.raises(InputError, match="first layer has a pace input") as err:
        load_deep_crbm(path)
    assert str(path) in str(err.value)


def test_a_pace_never_falls_below_standing_and_jumps_come_from_the_training_paces(paced, plain):
    prior = CRBMPrior([paced], pace_drift=0.5, pace_jump=0.5)
    rng = np.random.default_rng(4)
    low = np.full(20000, np.log(PACE_FLOOR_MM) - 0.2)
    out = prior.next_pace(paced, low, rng)
    assert out.min() == pytest.approx(np.log(PACE_FLOOR_MM))  # a negative ground speed means nothing
    fresh = prior.next_pace(paced, np.full(20000, 10.0), rng)  # far above every training pace
    drawn = fresh[np.abs(fresh - 10.0) > 3]
    assert len(drawn) / 20000 == pytest.approx(0.5, abs=0.02)
    assert np.mean(drawn) == pytest.approx(paced.pace_label[0], abs=0.02)
    assert np.std(drawn) == pytest.approx(paced.pace_label[1], rel=0.05)
    with pytest.raises(InputError, match="pace jump"):
        CRBMPrior([paced], pace_jump=1.5)
    with pytest.raises(InputError, match="pace input"):  # a setting that would do nothing is refused
        CRBMPrior([plain], pace_jump=0.1)


def test_the_pace_innovation_compares_the_step_taken_along_the_predicted_one_with_it():
    from priors.crbm import pace_innovation

    before = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 50.0]])
    predicted = before + [0.0, 10.0]  # every particle predicted 10 mm/frame along y
    sideways = before + [[7.0, 14.0], [5.0, 14.0], [9.0, 14.0]]  # 14 along, and 7 across that does not count
    assert pace_innovation(before, sideways, predicted) == pytest.approx(np.log(16 / 12))
    assert pace_innovation(before, predicted, predicted) == 0.0  # the prior's steps were the images' choice
    backwards = before - [0.0, 5.0]
    assert pace_innovation(before, backwards, predicted) == pytest.approx(np.log(PACE_FLOOR_MM / 12))
    standing = pace_innovation(before, before + [3.0, 4.0], before)  # no predicted direction: the step's length
    assert standing == pytest.approx(np.log((PACE_FLOOR_MM + 5) / PACE_FLOOR_MM))
    assert pace_innovation(before, sideways, np.full((3, 2), np.nan)) == 0.0  # nothing predicted yet


def test_a_pace_gain_moves_every_particles_pace_by_the_gain_times_the_images_correction(paced, walk_07_01):
    """The particles land 6 mm further along their predicted steps than the prior put them (the images chose
    longer steps): the next pace each particle is given is its own plus the gain times that frame's innovation,
    the same for all, so the paces keep their spread."""
    from priors.crbm import pace_innovation

    rng = np.random.default_rng(5)
    prior = CRBMPrior([paced], pace_drift=0.0, pace_gain=0.3)
    history = np.repeat(walk_07_01[None, 57:60], 50, axis=0)
    state = prior.start(walk_07_01[:60], 50, rng)
    assert np.all(np.isnan(state["ground_predicted"]))
    poses, state = prior.sample(history, 3, state, rng)
    assert np.all(np.isfinite(state["ground_predicted"]))
    step = (state["ground_predicted"] - history[:, -1, :2]).mean(axis=0)
    poses[:, :2] = state["ground_predicted"] + 6.0 * step / np.hypot(*step)
    history = np.concatenate([history[:, 1:], poses[:, None]], axis=1)
    innovation = pace_innovation(history[:, -2, :2], history[:, -1, :2], state["ground_predicted"])
    assert innovation > 0.1
    _, after = prior.sample(history, 3, state, rng)
    expected = np.maximum(state["pace"] + 0.3 * innovation, np.log(PACE_FLOOR_MM))
    assert np.allclose(after["pace"], expected)
    assert np.std(after["pace"]) == pytest.approx(np.std(state["pace"]))
    unchanged = CRBMPrior([paced], pace_drift=0.0)  # off by default: the pace is the particle's own
    assert unchanged.pace_gain == 0.0 and "ground_predicted" not in unchanged.start(walk_07_01[:60], 4, rng)


def test_a_pace_gain_is_checked(paced, plain):
    from tracker.app.api import prior_entry

    with pytest.raises(InputError, match="pace gain must be a fraction"):
        CRBMPrior([paced], pace_gain=1.5)
    with pytest.raises(InputError, match="pace input"):  # a setting that would do nothing is refused
        CRBMPrior([plain], pace_gain=0.1)
    with pytest.raises(InputError, match="ground velocity noise"):
        CRBMPrior([paced], pace_gain=0.1, ground_velocity_noise=0.5)
    option = {o.name: o for o in prior_entry("crbm").options}["pace_gain"]
    assert option.default == 0.0 and option.maximum == 1.0
