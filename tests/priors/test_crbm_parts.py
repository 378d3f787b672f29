"""The CRBM prior's parts (:mod:`priors.parts`): the pace input (``train --pace-input``) with the pace label of
training frames, a model whose gait speed follows the pace it is given and the per-particle pace while tracking;
each particle's root-height offset; the posture offset; their defaults for a paced model; the model file's
checks."""
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from priors.crbm.file import load_crbm
from priors.crbm.model import CRBMConfig
from priors.crbm.prior import CRBMPrior
from priors.crbm.training import train_crbm
from priors.parts import PACE_DRIFT, PACE_SPREAD, GroundDiffusion, HeightOffset, PaceInput, PostureOffset, Step
from tracker.core.body import DOF_NAMES, fifteen_cone_model
from tracker.core.errors import InputError
from tracker.core.representation import PACE_FLOOR_MM, clip_log_pace, poses_to_invariant
from tracker.core.timewarp import exp_map_triples, time_warp_clip

TRIPLES = exp_map_triples(fifteen_cone_model())


@pytest.fixture(scope="module")
def walk_07_01(mocap_dir):
    from data_tools.motion.asf_amc import asf_amc_clip
    from data_tools.motion.retarget import retarget

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
    prior = CRBMPrior([paced], gibbs_steps=5, pace=PaceInput(0.0, 0.0), ground=GroundDiffusion(0.0))
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
    pace = prior.part("pace")
    assert (pace.spread, pace.drift) == (PACE_SPREAD, PACE_DRIFT)
    rng = np.random.default_rng(1)
    state = prior.start(walk_07_01[:60], 4000, rng)
    step = poses_to_invariant(walk_07_01[58:60])[-1]
    known = np.log(PACE_FLOOR_MM + np.hypot(step[0], step[1]))
    assert np.mean(state["pace"]) == pytest.approx(known, abs=0.02)
    assert np.std(state["pace"]) == pytest.approx(PACE_SPREAD, rel=0.05)
    history = np.repeat(walk_07_01[None, 57:60], 4000, axis=0)
    _, after = prior.sample(history, 3, state, rng)
    moved = after["pace"] - state["pace"]
    assert np.std(moved) == pytest.approx(PACE_DRIFT, rel=0.05)
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
    assert CRBMPrior([plain]).part("pace") is None
    assert "pace" not in CRBMPrior([plain]).start(np.zeros((3, 40)), 2, None)
    assert plain.to_document()["pace_label"] is None


@pytest.mark.slow
def test_train_and_track_a_paced_model_from_the_command_line(mocap_dir, walk_32_frames, tmp_path):
    """``train --pace-input`` writes a paced model file; ``track`` with it records the posterior mean
    pace per frame in result.json and draws it."""
    import json
    import subprocess
    import sys

    model = tmp_path / "paced.pt"
    r = subprocess.run([sys.executable, "-m", "tracker", "train", "--prior", "crbm", "--mocap",
                        str(mocap_dir / "07" / "07_01.amc"), "--order", "2", "--epochs", "5", "--hidden", "20",
                        "--pace-input", "--out", str(model)], capture_output=True, text=True)
    assert r.returncode == 0 and "paced" in r.stdout, r.stderr[-500:]
    out = tmp_path / "t"
    r = subprocess.run([sys.executable, "-m", "tracker", "track", str(walk_32_frames.root), "--prior", "crbm",
                        "--model", str(model), "--particles", "100", "--frames", "6", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-500:]
    result = json.loads((out / "result.json").read_text())
    summary = result["prior_summary"]
    assert summary["names"] == ["pace (mm/frame)", "height offset (mm)", "posture offset rms (deg)"]
    assert len(summary["per_frame"]) == result["frames_tracked"]
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


def test_a_particles_height_offset_moves_the_models_heights_by_exactly_that_offset(paced, walk_07_01):
    """A particle whose history and offset are both 70 mm higher samples the same pose 70 mm higher: the model
    sees the same input."""
    prior = CRBMPrior([paced], pace=PaceInput(0.0, 0.0), height=HeightOffset(30.0))
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
    prior = CRBMPrior([paced], height=HeightOffset(40.0, 2.0), posture=PostureOffset(0.0))
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
    plain = CRBMPrior([paced], height=HeightOffset(0.0), posture=PostureOffset(0.0))
    assert "height_offset" not in plain.start(walk_07_01[:60], 10, rng) and len(plain.summary_names) == 1
    for bad in ((-1.0, 0.0), (0.0, float("nan"))):
        with pytest.raises(InputError, match="height"):
            HeightOffset(*bad)


def test_a_paced_crbm_gives_each_particle_a_height_offset_by_default(paced, plain, walk_07_01):
    from priors.crbm.prior import PACED_HEIGHT_SPREAD
    from tracker.app.api import prior_entry

    assert PACED_HEIGHT_SPREAD == 50.0 and CRBMPrior([paced]).part("height").spread == PACED_HEIGHT_SPREAD
    assert CRBMPrior([plain]).part("height") is None
    assert CRBMPrior([paced], height=HeightOffset(0.0)).part("height") is None
    option = {o.name: o for o in prior_entry("crbm").options}["height_spread"]
    assert option.default is None and "(default 50 for a model trained with a pace input" in option.described()
    state = CRBMPrior([paced]).start(walk_07_01[:60], 4000, np.random.default_rng(8))
    assert np.std(state["height_offset"]) == pytest.approx(PACED_HEIGHT_SPREAD, rel=0.05)


def test_a_paced_crbm_corrects_its_posture_by_default(paced, plain):
    from priors.crbm.prior import PACED_POSTURE_GAIN
    from tracker.app.api import prior_entry

    assert PACED_POSTURE_GAIN == 0.1 and CRBMPrior([paced]).part("posture").gain == PACED_POSTURE_GAIN
    assert CRBMPrior([plain]).part("posture") is None
    assert CRBMPrior([paced], posture=PostureOffset(0.0)).part("posture") is None
    option = {o.name: o for o in prior_entry("crbm").options}["posture_gain"]
    assert option.default is None and f"(default {PACED_POSTURE_GAIN:g} for a model" in option.described()
    deep = {o.name: o for o in prior_entry("deep-crbm").options}["posture_gain"]
    assert deep.default == 0.0


def test_height_offsets_selected_by_the_images_follow_a_shorter_person(paced, walk_07_01):
    """The same walk 100 mm lower, each frame's particles weighted by how close their root height is to the
    person's (a stand-in for the likelihood) and resampled: with height offsets the sampled heights follow the
    person, without them the model keeps pulling the particles back up to the training subject's height."""
    errors = {spread: height_error_on_a_lowered_walk(
        CRBMPrior([paced], pace=PaceInput(0.0, 0.0), height=HeightOffset(spread)),
        walk_07_01, particles=300, frames=40, seed=6, select_sd=20.0) for spread in (0.0, 60.0)}
    assert abs(errors[60.0]) < 25 and errors[0.0] > 40, errors


def test_by_default_a_pace_input_only_for_clips_of_several_paces(walk_07_01):
    from priors.crbm.training import paces_vary

    assert not paces_vary([walk_07_01], 60.0)  # one walk: a 1% spread of paces
    assert paces_vary([walk_07_01, time_warp_clip(walk_07_01, 0.6, TRIPLES)], 60.0)


def test_a_deep_crbm_file_with_a_paced_first_layer_is_refused(paced, tmp_path):
    from priors.deep_crbm.file import load_deep_crbm

    path = tmp_path / "deep.pt"
    torch.save({"format": "pose-tracker deep-crbm v1", "bottom": paced.to_document()}, path)
    with pytest.raises(InputError, match="first layer has a pace input") as err:
        load_deep_crbm(path)
    assert str(path) in str(err.value)


def test_a_pace_never_falls_below_standing_and_pace_settings_need_a_pace_input(paced, plain):
    rng = np.random.default_rng(4)
    low = np.full(20000, np.log(PACE_FLOOR_MM) - 0.2)
    part = PaceInput(drift=0.5)
    step = Step(previous=np.zeros((len(low), 40)), history=None, model=SimpleNamespace(pace_input=lambda p: p[:, None]))
    part.condition({"pace": low}, step, part.noise(len(low), rng))
    out = step.new["pace"]
    assert out.min() == pytest.approx(np.log(PACE_FLOOR_MM))  # a negative ground speed means nothing
    for bad in ((-0.1, 0.05), (0.3, 2.0)):
        with pytest.raises(InputError, match="pace"):
            PaceInput(*bad)
    with pytest.raises(InputError, match="pace input"):  # a setting that would do nothing is refused
        CRBMPrior([plain], pace=PaceInput())
