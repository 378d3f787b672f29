"""CRBM prior: training, scoring, generation, save/load, compatibility checks, CLI."""
import subprocess
import sys

import numpy as np
import pytest
import torch

from priors.crbm.file import load_crbm
from priors.crbm.model import CRBM, CRBMConfig, bernoulli
from priors.crbm.prior import CRBMPrior
from priors.crbm.training import make_windows, train_crbm
from priors.parts import GroundDiffusion, PostureOffset
from tracker.core.body import DOF_NAMES
from tracker.core.errors import InputError
from tracker.core.representation import poses_to_invariant, posture_features

CRBM_PARAMS = CRBM.PARAMS


@pytest.fixture(scope="module")
def walks(mocap_dir):
    """The four training walks of subject 7 at 60 Hz (07_11 stays held out)."""
    from data_tools.motion.asf_amc import asf_amc_clip
    from data_tools.motion.retarget import retarget

    asf = mocap_dir / "07" / "07.asf"
    return [retarget(asf_amc_clip(asf, mocap_dir / "07" / f"07_{i}.amc"), fps=60).poses
            for i in ("01", "02", "09", "10")]


@pytest.fixture(scope="module")
def crbm3(walks):
    return train_crbm(walks, CRBMConfig(order=3, hidden=100, epochs=150), 60.0, DOF_NAMES,
                      rng=np.random.default_rng(1))


def test_binary_samples_are_16_bit_uniforms_below_the_probabilities():
    """The sampler's contract, which every seeded CRBM/FCRBM result depends on (since 0.11.0): one uniform 16-bit
    integer per unit, four from each 64-bit draw of the generator, 1 where it is below ``p * 2^16``; float 0/1 in
    ``p``'s dtype, ``p`` left unchanged."""
    from priors.crbm.model import uniform16

    for dtype in (torch.float32, torch.float64):
        p = torch.rand(40, 7, generator=torch.Generator().manual_seed(1), dtype=dtype)
        kept = p.clone()
        h = bernoulli(p, torch.Generator().manual_seed(2))
        words = torch.empty(70, dtype=torch.int64).random_(-2 ** 63, 2 ** 63 - 1,
                                                            generator=torch.Generator().manual_seed(2))
        u = words.view(torch.int16).view(40, 7).to(torch.int64) + 2 ** 15  # 0 .. 2^16 - 1
        expected = (u < p * 2 ** 16).to(dtype)
        assert h.dtype == dtype and torch.equal(h, expected) and 0 < h.sum() < h.numel() and torch.equal(p, kept)
    # Every one of the four integers of a 64-bit draw covers the whole range, and the rates are right.
    u16 = uniform16((250_000, 4), torch.Generator().manual_seed(3), "cpu")
    u = u16.to(torch.int64)
    assert u16.dtype == torch.int16 and u.min() == -2 ** 15 and u.max() == 2 ** 15 - 1
    assert torch.all((u < 0).double().mean(0).sub(0.5).abs() < 0.005)
    for rate in (0.0, 0.01, 0.3, 0.999, 1.0):
        share = float(bernoulli(torch.full((1_000_000,), rate), torch.Generator().manual_seed(4)).mean())
        assert abs(share - rate) < 0.002


def test_windows_are_indexed_not_copied(walks):
    data = make_windows(walks[:2], 3, DOF_NAMES)
    n0 = len(walks[0]) - 1  # each clip's last frame (a repeated step) is dropped
    assert data.frames.shape[0] == n0 + len(walks[1]) - 1
    assert len(data.starts) == (n0 - 3) + (len(walks[1]) - 1 - 3)
    assert not np.any((data.starts.numpy() > n0 - 4) & (data.starts.numpy() < n0))  # none straddles clips


def test_contrastive_divergence_lowers_reconstruction_error(crbm3):
    errs = crbm3.reconstruction_errors
    assert len(errs) == 150 and errs[-1] < 0.4 * errs[0] and np.mean(errs[-10:]) < np.mean(errs[:10])


def test_training_is_deterministic(walks):
    cfg = CRBMConfig(order=1, hidden=20, epochs=3)
    a = train_crbm(walks[:1], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(5)).crbm.state_dict()
    b = train_crbm(walks[:1], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(5)).crbm.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_free_energy_lower_on_real_than_time_shuffled(crbm3, walk_07_11):
    held_out = walk_07_11.poses
    real = make_windows([held_out], 3, DOF_NAMES, crbm3.normaliser)
    shuffled_poses = held_out[np.random.default_rng(0).permutation(len(held_out))]
    fake = make_windows([shuffled_poses], 3, DOF_NAMES, crbm3.normaliser)

    def mean_free_energy(data):
        idx = data.starts[:, None] + torch.arange(4)
        w = data.frames[idx]
        return float(crbm3.crbm.free_energy(w[:, -1], w[:, :-1].reshape(len(w), -1)).mean())

    assert mean_free_energy(real) < mean_free_energy(fake) - 10.0


def test_free_energy_descent_finds_a_minimum(crbm3, walks):
    data = make_windows(walks[:1], 3, DOF_NAMES, crbm3.normaliser)
    idx = data.starts[:50, None] + torch.arange(4)
    w = data.frames[idx]
    hist = w[:, :-1].reshape(50, -1)
    start = w[:, -2]
    best = crbm3.crbm.best_guess(hist, init=start)
    assert float(crbm3.crbm.free_energy(best, hist).sum()) < float(crbm3.crbm.free_energy(start, hist).sum())
    v = best.clone().requires_grad_(True)
    crbm3.crbm.free_energy(v, hist).sum().backward()
    assert float(v.grad.abs().max()) < 1e-2


@pytest.mark.slow
def test_generated_walk_stays_in_range_and_keeps_walking(crbm3, walks):
    prior = CRBMPrior([crbm3], gibbs_steps=30, ground=GroundDiffusion(0.0))  # pure generation
    start = walks[0][:4]
    state = prior.start(start, 1, np.random.default_rng(0))
    hist = start[None, -3:]
    out = []
    rng = np.random.default_rng(3)
    for _ in range(500):
        x, state = prior.sample(hist, 3, state, rng)
        hist = np.concatenate([hist[:, 1:], x[:, None]], axis=1)
        out.append(x[0])
    gen = poses_to_invariant(np.array(out))
    train = np.concatenate([poses_to_invariant(w) for w in walks])
    assert np.all(np.isfinite(gen))
    span = train.max(0) - train.min(0)
    # Within the training range, up to a quarter of its span (measured: head_x, the worst, 12% beyond).
    assert np.all(gen.min(0) >= train.min(0) - 0.25 * span) and np.all(gen.max(0) <= train.max(0) + 0.25 * span)
    speed = gen[-200:, 0].mean()  # forward mm per frame
    per_clip = [poses_to_invariant(w)[:, 0].mean() for w in walks]
    assert min(per_clip) * 0.8 < speed < max(per_clip) * 1.2
    knee = np.array(out)[-120:, DOF_NAMES.index("left_knee_flexion")]
    assert np.ptp(knee) > 0.5  # still stepping (training walks swing the knee through ~1.2 rad)


def test_save_load_gives_identical_samples(crbm3, walks, tmp_path):
    crbm3.save(tmp_path / "m.pt")
    loaded = load_crbm(tmp_path / "m.pt")
    hist = np.repeat(walks[1][None, 10:13], 64, axis=0)

    def draw(model, seed=9):
        prior = CRBMPrior([model], gibbs_steps=10)
        state = prior.start(walks[1][:13], 64, np.random.default_rng(seed))
        return prior.sample(hist, 3, state, np.random.default_rng(seed))[0]

    assert np.array_equal(draw(crbm3), draw(loaded))
    assert not np.array_equal(draw(crbm3, 9), draw(crbm3, 10))  # the draws come from the generator passed in
    assert loaded.fps == 60.0 and loaded.order == 3 and loaded.dof_names == list(DOF_NAMES)


def test_model_and_sequence_mismatch_is_refused(crbm3, tmp_path):
    with pytest.raises(InputError, match="30 fps .trained at 60 fps"):
        crbm3.check_compatible("15-cone", DOF_NAMES, 30.0)
    with pytest.raises(InputError, match="body model 'bodytrack-10-cone'"):
        crbm3.check_compatible("bodytrack-10-cone", [f"d{i}" for i in range(31)], None)
    (tmp_path / "junk.pt").write_bytes(b"not a model")
    with pytest.raises(InputError, match="not a CRBM model file"):
        load_crbm(tmp_path / "junk.pt")


@pytest.mark.slow
def test_train_and_track_cli(mocap_dir, walk_32_frames, tmp_path):
    model = tmp_path / "c1.pt"
    amc = str(mocap_dir / "07" / "07_01.amc")
    r = subprocess.run([sys.executable, "-m", "tracker", "train", "--prior", "crbm", "--mocap", amc, "--order", "1",
                        "--epochs", "20", "--hidden", "30", "--out", str(model)], capture_output=True, text=True)
    assert r.returncode == 0 and "reconstruction error" in r.stdout, r.stderr[-500:]
    r = subprocess.run([sys.executable, "-m", "tracker", "track", str(walk_32_frames.root), "--prior", "crbm",
                        "--model", str(model), "--particles", "100", "--frames", "5", "--out", str(tmp_path / "t")],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "crbm" in r.stdout, r.stderr[-500:]
    for args, expected in [(["train", "--prior", "crbm", "--mocap", amc, "--order", "0", "--out", str(model)],
                            "must be at least 1"),
                           (["track", str(walk_32_frames.root), "--prior", "crbm", "--out", str(tmp_path / "u")],
                            "needs a model file"),
                           (["track", str(walk_32_frames.root), "--prior", "crbm", "--model", str(tmp_path / "no.pt"),
                             "--out", str(tmp_path / "u")], "model file not found")]:
        r = subprocess.run([sys.executable, "-m", "tracker", *args], capture_output=True, text=True)
        last = r.stderr.strip().splitlines()[-1]
        assert r.returncode == 2 and expected in last and "Traceback" not in r.stderr, (args, r.stderr[-300:])


@pytest.mark.slow
def test_a_higher_order_model_file_grows_from_its_own_lower_order(walk_32_frames, tmp_path):
    import tracker
    from data_tools.samples import sample_walks

    asf, walks = sample_walks()
    model = tracker.train("crbm", [walks[0]], skeletons=[asf], order=3, epochs=3, hidden=16, seed=0)
    assert [g.order for g in model.growth] == [1]
    model.save(tmp_path / "c3.pt")
    loaded = load_crbm(tmp_path / "c3.pt")
    assert [g.order for g in loaded.growth] == [1]
    res = tracker.track(walk_32_frames, "crbm", models=[tmp_path / "c3.pt"], particles=40, frames=6, seed=0)
    assert res.prior_per_frame == [{"first": 2, "last": 2, "model": "crbm order 1"},
                                   {"first": 3, "last": 5, "model": "crbm order 3"}]
    bare = tracker.train("crbm", [walks[0]], skeletons=[asf], order=3, epochs=2, hidden=16, grow_from="none")
    bare.save(tmp_path / "bare.pt")
    with pytest.raises(InputError, match="needs 3 known frame"):  # never a padded history
        tracker.track(walk_32_frames, "crbm", models=[tmp_path / "bare.pt"], particles=40, frames=6)
    ok = tracker.track(walk_32_frames, "crbm", models=[tmp_path / "bare.pt"], particles=40, frames=6,
                       known_frames=3)
    assert ok.prior_per_frame == [{"first": 3, "last": 5, "model": "crbm order 3"}]


@pytest.mark.parametrize("damage, expected", [
    (lambda d: d["params"].__setitem__("W", d["params"]["W"] * float("nan")), "W contains NaN"),
    (lambda d: d["params"].__setitem__("A", d["params"]["A"][:5]), "weight A has shape"),
    (lambda d: d["normaliser"].__setitem__("std", d["normaliser"]["std"] * 0), "positive scales"),
    (lambda d: d["normaliser"].__setitem__("std", d["normaliser"]["std"] * float("inf")), "finite"),
    (lambda d: d.pop("pose_step_rms"), "lacks 'pose_step_rms'"),
    (lambda d: d["config"].__setitem__("learning_rat", 1.0), "unknown settings learning_rat"),
    (lambda d: d.__setitem__("fps", "sixty"), "fps must be a number"),
])
def test_broken_model_files_are_refused(crbm3, tmp_path, damage, expected):
    doc = crbm3.to_document()
    damage(doc)
    torch.save(doc, tmp_path / "bad.pt")
    with pytest.raises(InputError, match=expected):
        load_crbm(tmp_path / "bad.pt")


@pytest.mark.slow
def test_interrupted_training_resumes_to_the_same_model(tmp_path):
    import tracker
    from data_tools.samples import sample_walks

    asf, walks = sample_walks()
    settings = dict(skeletons=[asf], order=3, epochs=6, hidden=16, seed=0, checkpoint_every=2)
    whole = tracker.train("crbm", [walks[0]], **settings)
    calls = []

    def interrupt(done, total, metrics):  # Ctrl-C in the order-3 stage, after its checkpoint at epoch 4
        calls.append(done)
        if len(calls) == 11:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        tracker.train("crbm", [walks[0]], checkpoint=tmp_path / "c.pt", progress=interrupt, **settings)
    assert (tmp_path / "c.pt").exists()
    resumed = tracker.train("crbm", [walks[0]], checkpoint=tmp_path / "c.pt", resume=True, **settings)
    for a, b in [(whole, resumed), (whole.growth[0], resumed.growth[0])]:
        assert all(torch.equal(a.crbm.state_dict()[k], b.crbm.state_dict()[k]) for k in CRBM_PARAMS)
    assert resumed.reconstruction_errors == whole.reconstruction_errors and not (tmp_path / "c.pt").exists()
    with pytest.raises(InputError, match="no training checkpoint"):
        tracker.train("crbm", [walks[0]], checkpoint=tmp_path / "c.pt", resume=True, **settings)


def test_split_validation_holds_out_the_end_of_each_clip():
    from priors.crbm.training import split_validation

    # Order-2 windows of clips of 10 and 6 frames (none predicts a clip's last frame, see make_windows).
    starts = torch.tensor([0, 1, 2, 3, 4, 5, 6, 10, 11, 12])
    train, held = split_validation(starts, [10, 6], 2, 0.34)  # the last 3 and 2 frames of each clip
    assert held.tolist() == [5, 6, 12] and train.tolist() == [0, 1, 2, 3, 4, 10, 11]
    assert split_validation(starts, [10, 6], 2, 0.0)[1].numel() == 0
    with pytest.raises(InputError, match="no windows to hold out"):
        split_validation(torch.tensor([0, 1]), [4], 1, 0.1)


@pytest.mark.slow
def test_validation_keeps_the_weights_of_the_best_held_out_check(walks):
    """With 30% of a short clip held out and a fast learning rate, the held-out error is least before the last
    epoch; the model keeps those weights: the same training stopped at that epoch ends with the same weights."""
    clip = walks[0][:150]
    cfg = CRBMConfig(order=2, hidden=100, epochs=200, validation=0.3, validation_every=5, learning_rate=1e-2)
    whole = train_crbm([clip], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(1))
    errors = dict((int(e), x) for e, x in whole.validation_errors)
    assert sorted(errors) == list(range(5, 201, 5)) and 0 < whole.best_epoch < 200
    assert errors[whole.best_epoch] == min(errors.values())
    stopped = train_crbm([clip], CRBMConfig(**{**cfg.__dict__, "epochs": whole.best_epoch}), 60.0, DOF_NAMES,
                         rng=np.random.default_rng(1))
    assert all(torch.equal(whole.crbm.state_dict()[k], stopped.crbm.state_dict()[k]) for k in CRBM_PARAMS)
    assert f"at epoch {whole.best_epoch} (kept)" in whole.summary()


def test_training_with_validation_resumes_to_the_same_model(walks, tmp_path):
    cfg = CRBMConfig(order=1, hidden=20, epochs=8, validation=0.2, validation_every=2)
    states = []
    whole = train_crbm(walks[:2], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(2),
                       checkpoint=(lambda model, state: states.append(state), 4))
    resumed = train_crbm(walks[:2], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(2), resume=states[0])
    assert states[0]["best"]["epoch"] in (2, 4)
    assert all(torch.equal(whole.crbm.state_dict()[k], resumed.crbm.state_dict()[k]) for k in CRBM_PARAMS)
    assert resumed.validation_errors == whole.validation_errors and resumed.best_epoch == whole.best_epoch
    whole.save(tmp_path / "m.pt")
    loaded = load_crbm(tmp_path / "m.pt")
    assert loaded.best_epoch == whole.best_epoch and loaded.validation_errors == whole.validation_errors


def test_two_models_of_one_order_are_refused_not_silently_dropped(crbm3):
    with pytest.raises(InputError, match="one model per order"):
        CRBMPrior([crbm3, crbm3])


def test_the_history_noise_option_is_auto_or_a_number_in_range():
    from priors.crbm.training import parse_history_noise

    assert parse_history_noise("auto") == "auto" and parse_history_noise("0.5") == 0.5 and parse_history_noise(0) == 0
    for bad, expected in [("abc", "'auto' or a number"), ("200", r"\[0, 100\]"), (-1, r"\[0, 100\]")]:
        with pytest.raises(InputError, match=expected):
            parse_history_noise(bad)


def test_a_posture_offset_shifts_the_models_history_and_prediction_alike(crbm3, walks):
    """The model sees the history less the posture offset and its prediction is moved back by it: a walk whose joint
    angles are all 0.1 rad off, tracked with an offset of 0.1 rad, is predicted exactly as the walk itself plus 0.1."""
    known = walks[2][:4]
    shifted = known.copy()
    shifted[:, 6:] += 0.1
    prior = CRBMPrior([crbm3], mode="free-energy", ground=GroundDiffusion(0.0), posture=PostureOffset(0.5))
    rng = np.random.default_rng(0)
    predictions = []
    for history, offset in ((known, 0.0), (shifted, 0.1)):
        state = prior.start(history, 3, rng)
        posture = posture_features(known.shape[1])
        state["posture_offset"][:, posture.index(6):] = offset  # the joint angles' (not the root's pitch, roll)
        poses, new = prior.sample(np.repeat(history[None, 1:], 3, axis=0), 3, state, rng)
        predictions.append(poses)
        assert np.allclose(new["posture_offset"], state["posture_offset"])  # no prediction yet: nothing moved
    assert np.allclose(predictions[1][:, 6:], predictions[0][:, 6:] + 0.1, atol=1e-5)
    assert np.allclose(predictions[1][:, :6], predictions[0][:, :6], atol=1e-3)


def test_the_posture_offset_integrates_the_images_mean_correction(crbm3, walks):
    """When the resampled particles sit a constant 0.05 rad from the prior's mean prediction on every joint angle,
    the offset moves by the gain times 0.05 on those angles and by nothing on the root's pitch and roll; the
    default (no gain) carries no offset state at all."""
    from priors.parts import updated_posture_offset

    assert np.array_equal(updated_posture_offset(np.ones(2), np.zeros((3, 2)), np.full(2, np.nan), 0.5), np.ones(2))
    assert np.allclose(updated_posture_offset(np.ones(2), np.full((3, 2), 0.3), np.full(2, 0.1), 0.5), [1.1, 1.1])
    known = walks[2][:4]
    prior = CRBMPrior([crbm3], mode="free-energy", ground=GroundDiffusion(0.0), posture=PostureOffset(0.25))
    rng = np.random.default_rng(0)
    state = prior.start(known, 4, rng)
    history = np.repeat(known[None, 1:], 4, axis=0)
    poses, state = prior.sample(history, 3, state, rng)
    moved = poses.copy()
    moved[:, 6:] += 0.05
    _, state = prior.sample(np.concatenate([history[:, 1:], moved[:, None]], axis=1), 3, state, rng)
    posture = posture_features(known.shape[1])
    root = posture.index(6)
    assert np.allclose(state["posture_offset"][:, root:], 0.25 * 0.05, atol=1e-6)
    assert np.allclose(state["posture_offset"][:, :root], 0.0, atol=1e-6)
    assert prior.summarize(state, np.full(4, 0.25))[-1] > 0
    assert "posture_offset" not in CRBMPrior([crbm3]).start(known, 4, rng)
    with pytest.raises(InputError, match="posture gain"):
        CRBMPrior([crbm3], posture=PostureOffset(1.5))


@pytest.mark.parametrize("setting, value, rule", [
    ("sparsity_target", 1.0, "CRBM: sparsity must be greater than 0 and less than 1"),
    ("sparsity_target", 0.0, "CRBM: sparsity must be greater than 0 and less than 1"),
    ("validation", 0.6, "CRBM: validation must be at least 0 and at most 0.5"),
])
def test_a_training_config_is_checked_by_the_options_bounds(setting, value, rule):
    """The config refuses what the command line's option refuses, in the option's words: one declaration."""
    from priors.crbm.model import CRBMConfig
    from priors.settings import crbm_train_option

    with pytest.raises(InputError, match=rule):
        CRBMConfig(**{setting: value}).check()
    name = "sparsity" if setting == "sparsity_target" else setting
    with pytest.raises(InputError, match=rule.replace("CRBM", "train")):
        crbm_train_option(name).parse(value, "train")
