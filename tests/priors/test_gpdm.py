"""GPDM core: objective and its gradients, training, mean prediction, save/load, a singular kernel."""
import numpy as np
import pytest
import torch

from priors.gpdm.file import load_gpdm
from priors.gpdm.model import GPDM, GPDMConfig, save_gpdm
from priors.gpdm.predict import prepare
from priors.gpdm.training import train_gpdm
from priors.parts import GroundDiffusion, HeightOffset
from tracker.core.errors import InputError
from tracker.engine.prior import summarize, summary_of


def noise_row(noise, i: int):
    """Row ``i`` of a step's random numbers (:meth:`priors.learned.LearnedPrior.step_noise`): the GPDM's latent
    noise and each part's."""
    from priors.learned import StepNoise

    return StepNoise(noise.model[i:i + 1], [None if z is None else z[i:i + 1] for z in noise.parts])


@pytest.fixture(scope="module")
def walk_features(walk_07_01):
    """07_01's invariant features, normalised (one 157-frame sequence)."""
    from tracker.core.body import DOF_NAMES
    from tracker.core.representation import FeatureNormaliser, feature_names, poses_to_invariant

    f = poses_to_invariant(walk_07_01.poses)[:-1]
    norm = FeatureNormaliser.fit(f, feature_names(DOF_NAMES))
    return norm.transform(f)


@pytest.fixture(scope="module")
def trained(walk_features):
    return train_gpdm(walk_features, [len(walk_features)], GPDMConfig(iterations=120))


def test_autograd_gradients_match_finite_differences(walk_features):
    Y = walk_features[:40, :6]
    for cfg in (GPDMConfig(dynamics="linear+rbf", order=2, balance=3.0), GPDMConfig(dynamics="rbf"),
                GPDMConfig(dynamics="linear")):
        m = GPDM(Y, [20, 20], cfg)
        m.update_W()
        params = m.parameters()
        value = m.objective()
        grads = torch.autograd.grad(value, params)
        rng = np.random.default_rng(0)
        for p, g in zip(params, grads):
            for _ in range(4):
                idx = tuple(int(rng.integers(s)) for s in p.shape)
                eps = 1e-6
                with torch.no_grad():
                    p[idx] += eps
                    up = float(m.objective())
                    p[idx] -= 2 * eps
                    down = float(m.objective())
                    p[idx] += eps
                fd = (up - down) / (2 * eps)
                assert fd == pytest.approx(float(g[idx]), rel=1e-4, abs=1e-5)


def test_objective_decreases_during_training(trained):
    h = trained.objective_history
    assert len(h) == 12 and h[-1] < h[0] - 1000 and all(b <= a + 1e-6 for a, b in zip(h, h[1:]))


def test_mean_prediction_stays_on_a_stable_cycle(trained):
    p = prepare(trained)
    X = trained.X.detach()
    traj = p.simulate(X[:1], 500)
    lo, hi = X.min(0).values, X.max(0).values
    span = hi - lo
    assert torch.all(traj >= lo - 0.1 * span) and torch.all(traj <= hi + 0.1 * span)
    late = traj[-200:]
    # Still moving around a cycle, not collapsed to a fixed point: the path length per step stays near the data's.
    step = (late[1:] - late[:-1]).norm(dim=1).mean()
    data_step = (X[1:] - X[:-1]).norm(dim=1).mean()
    assert 0.3 * data_step < step < 3 * data_step
    pose, var = p.predict_pose(late[:5])
    assert pose.shape == (5, trained.Y.shape[1]) and torch.all(var > 0)


def test_save_load_round_trip(trained, tmp_path):
    save_gpdm(tmp_path / "g.pt", trained, {"fps": 60.0})
    loaded, extra = load_gpdm(tmp_path / "g.pt")
    assert extra == {"fps": 60.0}
    a, b = prepare(trained), prepare(loaded)
    x = trained.X.detach()[10:15]
    assert torch.allclose(a.predict_pose(x)[0], b.predict_pose(x)[0])
    assert torch.allclose(a.simulate(x[:1], 20), b.simulate(x[:1], 20))
    with torch.no_grad():
        assert float(loaded.objective()) == pytest.approx(float(trained.objective()))


def test_singular_kernel_gives_a_clear_error(walk_features):
    Y = walk_features[:30]
    X = np.zeros((30, 3))  # every latent point the same
    m = GPDM(Y, [30], GPDMConfig(), X=X)
    with torch.no_grad():
        m.log_beta[2] = 80.0  # no observation noise
        m.log_alpha[-1] = 80.0
    with pytest.raises(InputError, match="kernel matrix is not positive definite"):
        m.objective()


def test_bad_config_and_data():
    with pytest.raises(InputError, match="dynamics kernel"):
        GPDMConfig(dynamics="cubic").check()
    with pytest.raises(InputError, match="more than 2 frames"):
        GPDM(np.zeros((4, 3)), [2, 2], GPDMConfig(order=2))


@pytest.fixture(scope="module")
def gpdm_prior_model(walk_07_01):
    from priors.gpdm.training import train_gpdm_prior
    from tracker.core.body import DOF_NAMES

    return train_gpdm_prior([walk_07_01.poses], GPDMConfig(iterations=100), 60.0, DOF_NAMES, sources=["07_01"])


def test_gpdm_prior_samples_a_batch_of_walking_poses(gpdm_prior_model, walk_07_01):
    from priors.gpdm.prior import GPDMPrior

    prior = GPDMPrior(gpdm_prior_model, ground=GroundDiffusion(0.0))
    known = walk_07_01.poses[:2]
    state = prior.start(known, 200, np.random.default_rng(0))
    assert state["latent"].shape == (200, 3) and state["step"].shape == (200, 3)
    hist = np.repeat(known[None, -1:], 200, axis=0)
    rng = np.random.default_rng(1)
    poses = []
    for _ in range(30):
        x, state = prior.sample(hist, 1, state, rng)
        hist = x[:, None]
        poses.append(x)
    poses = np.stack(poses, axis=1)  # 200 x 30 x 40
    assert np.all(np.isfinite(poses))
    travelled = np.linalg.norm(poses[:, -1, :2] - known[-1, :2], axis=1)
    truth = np.linalg.norm(walk_07_01.poses[31, :2] - walk_07_01.poses[1, :2])
    assert np.median(travelled) == pytest.approx(truth, rel=0.25)  # walks on at about the true speed
    assert np.std(poses[:, -1, 6:], axis=0).max() > 1e-3  # the particles spread


def test_gpdm_prior_file_round_trip_and_mismatch(gpdm_prior_model, tmp_path):
    from priors.gpdm.file import load_gpdm_prior

    gpdm_prior_model.save(tmp_path / "g.pt")
    loaded = load_gpdm_prior(tmp_path / "g.pt")
    assert loaded.fps == 60.0 and loaded.sources == ["07_01"] and np.allclose(loaded.normaliser.mean,
                                                                               gpdm_prior_model.normaliser.mean)
    with pytest.raises(InputError, match="30 fps"):
        loaded.check_compatible("15-cone", loaded.dof_names, 30.0)


@pytest.mark.slow
def test_train_and_track_gpdm_cli(mocap_dir, walk_32_frames, tmp_path):
    import subprocess
    import sys

    model = tmp_path / "g.pt"
    amc = str(mocap_dir / "07" / "07_01.amc")
    r = subprocess.run([sys.executable, "-m", "tracker", "train", "--prior", "gpdm", "--mocap", amc,
                        "--iterations", "20", "--out", str(model)], capture_output=True, text=True)
    assert r.returncode == 0 and "objective" in r.stdout, r.stderr[-500:]
    r = subprocess.run([sys.executable, "-m", "tracker", "track", str(walk_32_frames.root), "--prior", "gpdm",
                        "--model", str(model), "--particles", "100", "--frames", "5", "--out", str(tmp_path / "t")],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "gpdm" in r.stdout, r.stderr[-500:]
    r = subprocess.run([sys.executable, "-m", "tracker", "train", "--prior", "gpdm", "--mocap", amc, "--order", "3",
                        "--out", str(model)], capture_output=True, text=True)
    assert r.returncode == 2 and "argument --order: must be one of 1, 2" in r.stderr.strip().splitlines()[-1]


# --- sparse (inducing-point) GPDM and the batched prior step ---------------------------------------------------

def test_sparse_gradients_match_finite_differences(walk_features):
    from priors.gpdm.model import inducing_frames

    Y = walk_features[:40, :6]
    m = GPDM(Y, [20, 20], GPDMConfig(order=2, balance=3.0), active=inducing_frames(Y, 12))
    m.update_W()
    assert m.sparse and len(m.active) == 12
    grads = torch.autograd.grad(m.objective(), m.parameters())
    rng = np.random.default_rng(0)
    for p, g in zip(m.parameters(), grads):
        for _ in range(4):
            idx = tuple(int(rng.integers(s)) for s in p.shape)
            with torch.no_grad():
                p[idx] += 1e-6
                up = float(m.objective())
                p[idx] -= 2e-6
                down = float(m.objective())
                p[idx] += 1e-6
            assert (up - down) / 2e-6 == pytest.approx(float(g[idx]), rel=1e-4, abs=1e-5)


def test_inducing_setting_and_frame_choice(walk_features):
    from priors.gpdm.model import AUTO_INDUCING, EXACT_MAX_FRAMES, inducing_frames

    assert GPDMConfig().inducing_count(EXACT_MAX_FRAMES) == 0
    assert GPDMConfig().inducing_count(EXACT_MAX_FRAMES + 1) == AUTO_INDUCING
    assert GPDMConfig(inducing=0).inducing_count(5000) == 0 and GPDMConfig(inducing=50).inducing_count(30) == 30
    with pytest.raises(InputError, match="at least 10"):
        GPDMConfig(inducing=3).check()
    idx = inducing_frames(walk_features, 30)
    assert len(set(idx)) == 30 and np.all(np.diff(idx) > 0) and np.array_equal(idx, inducing_frames(walk_features, 30))
    # Farthest-point: every frame is closer to a chosen one than the chosen ones are to each other, at most.
    d = np.linalg.norm(walk_features[:, None] - walk_features[idx][None], axis=-1)
    assert d.min(1).max() <= np.sort(d[idx], axis=1)[:, 1].min() + 1e-9
    assert GPDM(walk_features, [len(walk_features)], GPDMConfig()).active is None  # small data: exact


@pytest.fixture(scope="module")
def two_walks(walk_features, walk_07_11):
    """07_01 and 07_11 (about 310 frames), normalised with 07_01's statistics."""
    from tracker.core.body import DOF_NAMES
    from tracker.core.representation import FeatureNormaliser, feature_names, poses_to_invariant

    f = poses_to_invariant(walk_07_11.poses)[:-1]
    return walk_features, FeatureNormaliser.fit(f, feature_names(DOF_NAMES)).transform(f)


def test_sparse_training_decreases_a_finite_objective(two_walks):
    a, b = two_walks
    m = train_gpdm(np.concatenate([a, b]), [len(a), len(b)], GPDMConfig(iterations=60, inducing=40))
    h = m.objective_history
    assert m.sparse and len(m.active) == 40 and len(h) == 6
    assert all(np.isfinite(h)) and h[-1] < h[0] - 1000 and all(y <= x + 1e-6 for x, y in zip(h, h[1:]))


def test_sparse_prediction_with_every_frame_inducing_matches_exact(trained):
    sparse = GPDM(trained.Y.numpy(), trained.lengths, trained.config, X=trained.X.detach().numpy(),
                  active=np.arange(len(trained.Y)))
    with torch.no_grad():
        sparse.log_alpha.copy_(trained.log_alpha)
        sparse.log_beta.copy_(trained.log_beta)
    sparse.W = trained.W.clone()
    a, b = prepare(trained), prepare(sparse)
    x = trained.X.detach()[::7] + 0.05
    for (m1, v1), (m2, v2) in ((a.predict_latent(x), b.predict_latent(x)), (a.predict_pose(x), b.predict_pose(x))):
        assert torch.allclose(m1, m2, rtol=1e-3, atol=1e-3 * float(m1.abs().max()))
        assert torch.allclose(v1, v2, rtol=2e-2, atol=1e-6)
    with torch.no_grad():
        assert float(sparse.objective()) == pytest.approx(float(trained.objective()), rel=1e-3)


def test_sparse_model_round_trips_and_old_files_load_exact(two_walks, tmp_path):
    a, b = two_walks
    m = train_gpdm(np.concatenate([a, b]), [len(a), len(b)], GPDMConfig(iterations=10, inducing=40))
    save_gpdm(tmp_path / "s.pt", m)
    loaded, _ = load_gpdm(tmp_path / "s.pt")
    assert loaded.config.inducing == 40 and torch.equal(loaded.active, m.active)
    x = m.X.detach()[::11]
    p, q = prepare(m), prepare(loaded)
    assert torch.equal(p.predict_pose(x)[0], q.predict_pose(x)[0]) and torch.equal(p.simulate(x[:1], 10),
                                                                                       q.simulate(x[:1], 10))
    with torch.no_grad():
        assert float(loaded.objective()) == float(m.objective())
    doc = torch.load(tmp_path / "s.pt", weights_only=True)  # as written before sparse models existed
    del doc["active"], doc["config"]["inducing"]
    torch.save(doc, tmp_path / "old.pt")
    old, _ = load_gpdm(tmp_path / "old.pt")
    assert old.active is None and old.config.inducing is None


@pytest.fixture(scope="module")
def sparse_prior_model(gpdm_prior_model, walk_07_01, walk_07_11):
    from priors.gpdm.training import train_gpdm_prior
    from tracker.core.body import DOF_NAMES

    return train_gpdm_prior([walk_07_01.poses, walk_07_11.poses], GPDMConfig(iterations=30, inducing=40), 60.0,
                            DOF_NAMES)


@pytest.mark.parametrize("which,dtype", [("exact", torch.float64), ("sparse", torch.float64), ("exact", torch.float32),
                                         ("sparse", torch.float32)])
def test_prior_step_batched_equals_looped_and_is_seeded(which, dtype, gpdm_prior_model, sparse_prior_model,
                                                        walk_07_01):
    from priors.gpdm.prior import GPDMPrior

    model = gpdm_prior_model if which == "exact" else sparse_prior_model
    assert model.gpdm.sparse == (which == "sparse")
    prior = GPDMPrior(model, dtype=dtype)
    known = walk_07_01.poses[:2]
    P = 6
    state = prior.start(known, P, np.random.default_rng(0))
    state["latent"] = state["latent"] + 0.1 * np.random.default_rng(1).standard_normal(state["latent"].shape)
    hist = np.repeat(known[None, -1:], P, axis=0) + np.random.default_rng(2).normal(0, 1e-3, (P, 1, 40))
    batched, bstate = prior.sample(hist, 1, state, np.random.default_rng(7))
    noise = prior.step_noise(P, 1, np.random.default_rng(7))  # the same generator state: the same draws
    rows = [prior.advance(hist[i:i + 1], 1, {k: v[i:i + 1] for k, v in state.items()}, noise_row(noise, i))
            for i in range(P)]
    # Up to rounding: the float32 variance product sums in another order for one row than for six (differences
    # of about 2e-5 in latent units, where a step is about 0.1, and in rad).
    tol = 1e-10 if dtype == torch.float64 else 2e-4
    assert np.allclose(batched, np.concatenate([r[0] for r in rows]), rtol=tol, atol=tol)
    for k in bstate:
        assert np.allclose(bstate[k], np.concatenate([r[1][k] for r in rows]), rtol=tol, atol=tol)
    again, astate = prior.sample(hist, 1, state, np.random.default_rng(7))
    assert np.array_equal(batched, again) and all(np.array_equal(bstate[k], astate[k]) for k in bstate)
    other, _ = prior.sample(hist, 1, state, np.random.default_rng(8))
    assert not np.allclose(batched, other)


def test_float32_step_agrees_with_float64_prediction(gpdm_prior_model, sparse_prior_model):
    for model in (gpdm_prior_model, sparse_prior_model):
        p = prepare(model.gpdm)
        inputs = model.gpdm.X.detach()[::3] + 0.05 * torch.randn(1, 3, generator=torch.Generator().manual_seed(0))
        noise = torch.randn(inputs.shape, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
        x32, pose32 = p.sampler(torch.float32).step(inputs, noise, 1.0)
        x64, pose64 = p.sampler(torch.float64).step(inputs, noise, 1.0)
        mean, var = p.predict_latent(inputs)
        assert torch.allclose(x64, mean + var.sqrt()[:, None] * noise)
        assert torch.allclose(pose64, p.predict_pose(x64)[0])
        # The float32 variance moves the sample by under 1% of the latent noise (measured 0.6% exact, 0.3%
        # sparse), and the pose by under 0.5% of a feature's standard deviation (0.1%).
        assert float((x32 - x64).abs().max()) < 0.01 * float(var.sqrt().min())
        assert float((pose32 - pose64).abs().max()) < 0.005


def test_inducing_is_a_training_option(walk_07_01):
    import tracker

    model = tracker.train("gpdm", [walk_07_01], iterations=10, inducing=40)
    assert model.gpdm.sparse and len(model.gpdm.active) == 40 and "40 inducing" in model.summary()
    with pytest.raises(InputError, match="at least 10"):
        tracker.train("gpdm", [walk_07_01], iterations=10, inducing=5)


# --- training resume and model-file checks ---------------------------------------------------------------------

@pytest.mark.slow
def test_interrupted_training_resumes_to_the_same_model(tmp_path):
    """The checkpoint holds the L-BFGS optimiser's whole state (its step history, last direction and step
    length), so the resumed run continues bit for bit (restarting L-BFGS at iteration 20 without it ended
    0.10 away in X after 50 iterations)."""
    import tracker
    from data_tools.samples import sample_walks
    from priors.gpdm.training import GPDM_PARAMETERS

    asf, walks = sample_walks()
    settings = dict(skeletons=[asf], iterations=30, seed=0, checkpoint_every=10)
    whole = tracker.train("gpdm", [walks[0]], **settings)
    checkpoint = tmp_path / "g.pt.checkpoint"
    calls = []

    def interrupt(done, total, metrics):  # Ctrl-C at iteration 30, after the checkpoint at iteration 20
        calls.append(done)
        if len(calls) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        tracker.train("gpdm", [walks[0]], checkpoint=checkpoint, progress=interrupt, **settings)
    with pytest.raises(InputError, match="not a GPDM model file"):  # never taken for a model
        load_gpdm(checkpoint)
    with pytest.raises(InputError, match="not of this training"):
        tracker.train("gpdm", [walks[0]], checkpoint=checkpoint, resume=True, **{**settings, "iterations": 40})
    resumed = tracker.train("gpdm", [walks[0]], checkpoint=checkpoint, resume=True, **settings)
    for name in GPDM_PARAMETERS:
        assert torch.equal(getattr(whole.gpdm, name), getattr(resumed.gpdm, name)), name
    assert resumed.gpdm.objective_history == whole.gpdm.objective_history and not checkpoint.exists()
    with pytest.raises(InputError, match="no training checkpoint"):
        tracker.train("gpdm", [walks[0]], checkpoint=checkpoint, resume=True, **settings)


@pytest.fixture(scope="module")
def small_gpdm_file(tmp_path_factory):
    """A GPDM prior trained for 10 iterations on the shipped walk 07_01, saved."""
    import tracker
    from data_tools.samples import sample_walks

    asf, walks = sample_walks()
    path = tmp_path_factory.mktemp("gpdm") / "g.pt"
    tracker.train("gpdm", [walks[0]], skeletons=[asf], iterations=10).save(path)
    return path


def _extra(key, value):
    return lambda d: d["extra"].__setitem__(key, value)


def _normaliser(key, factor):
    return lambda d: d["extra"]["normaliser"].__setitem__(key, d["extra"]["normaliser"][key] * factor)


@pytest.mark.parametrize("damage, expected", [
    (lambda d: d.pop("X"), "lacks 'X'"),
    (lambda d: d.__setitem__("X", d["X"][:, :2]), "X has shape"),
    (lambda d: d.__setitem__("log_alpha", d["log_alpha"][:1]), "log_alpha has shape"),
    (lambda d: d.__setitem__("Y", d["Y"].tolist()), "Y must be a tensor of real numbers"),
    (lambda d: d.__setitem__("X", d["X"] * float("nan")), "X contains NaN or infinite"),
    (lambda d: d["log_beta"].__setitem__(2, float("inf")), "log_beta contains NaN or infinite"),
    (lambda d: d["log_alpha"].__setitem__(0, -40.0), "log_alpha[0] = -40: kernel scales"),
    (lambda d: d.__setitem__("W", d["W"] * 0), "W must be positive"),
    (lambda d: d["config"].__setitem__("latent_dims", 3), "unknown settings latent_dims"),
    (lambda d: d["config"].__setitem__("latent_dim", "3"), "latent_dim must be a finite number"),
    (lambda d: d["config"].__setitem__("dynamics", "cubic"), "dynamics kernel must be one of"),
    (lambda d: d.__setitem__("lengths", [5]), "Y has shape"),
    (lambda d: d.__setitem__("lengths", "157"), "lengths must be a list"),
    (lambda d: d.__setitem__("active", torch.tensor([0, 10 ** 6])), "inducing frames"),
    (lambda d: d.__setitem__("extra", [1]), "extra must be a dictionary"),
    (_extra("fps", "sixty"), "fps must be a number in (0, 100000] Hz, got 'sixty'"),
    (_extra("fps", 1e308), "fps must be a number"),
    (_extra("dof_names", 5), "dof_names must be a list of text"),
    (_extra("pose_step_rms", torch.full((40,), float("nan"))), "pose_step_rms must be finite"),
    (_normaliser("std", 0.0), "positive scales"),
    (_normaliser("std", float("inf")), "finite"),
    (lambda d: d["extra"].pop("normaliser"), "lacks 'normaliser'"),
])
def test_broken_model_files_are_refused(small_gpdm_file, tmp_path, damage, expected):
    from priors.gpdm.file import load_gpdm_prior

    doc = torch.load(small_gpdm_file, weights_only=True)
    damage(doc)
    bad = tmp_path / "bad.pt"
    torch.save(doc, bad)
    with pytest.raises(InputError) as err:
        load_gpdm_prior(bad)
    assert expected in str(err.value) and err.value.path == str(bad) and "\n" not in str(err.value)


def test_foreign_and_corrupt_model_files_are_refused(small_gpdm_file, tmp_path):
    from priors.gpdm.file import load_gpdm_prior

    text, cut, other = tmp_path / "text.pt", tmp_path / "cut.pt", tmp_path / "other.pt"
    text.write_text("not a model\n")
    cut.write_bytes(small_gpdm_file.read_bytes()[:2000])
    torch.save({"format": "pose-tracker crbm v1"}, other)
    for path, expected in ((text, "not a GPDM model file"), (cut, "not a GPDM model file"),
                           (other, "not a GPDM model file")):
        with pytest.raises(InputError, match=expected) as err:
            load_gpdm_prior(path)
        assert err.value.path == str(path)
    assert load_gpdm_prior(small_gpdm_file).fps == 60.0


def test_latent_dimension_above_the_features_is_refused():
    with pytest.raises(InputError, match="latent dimension must be at most the 3 observed features, got 4"):
        GPDM(np.random.default_rng(0).standard_normal((10, 3)), [10], GPDMConfig(latent_dim=4))


def test_a_particles_height_offset_moves_the_gpdms_heights_by_exactly_that_offset(gpdm_prior_model, walk_07_01):
    """The same latent history and noise with an offset of 70 mm give the same pose 70 mm higher."""
    from priors.gpdm.prior import GPDMPrior

    prior = GPDMPrior(gpdm_prior_model, height=HeightOffset(30.0))
    assert prior.summary_names == ("height offset (mm)",) and prior.summary_kind == "quantity"
    state = prior.start(walk_07_01.poses[:2], 20, np.random.default_rng(0))
    hist = np.repeat(walk_07_01.poses[None, 1:2], 20, axis=0)
    noise = prior.step_noise(20, 1, np.random.default_rng(1))
    out = []
    for offset in (0.0, 70.0):
        poses, new = prior.advance(hist, 1, {**state, "height_offset": np.full(20, offset)}, noise)
        assert np.all(new["height_offset"] == offset)  # no drift: the offset keeps its value
        out.append(poses)
    assert np.allclose(out[1][:, 2] - out[0][:, 2], 70.0, atol=1e-6)
    assert np.allclose(np.delete(out[1], 2, axis=1), np.delete(out[0], 2, axis=1), atol=1e-6)


def test_gpdm_height_offsets_start_spread_drift_are_summarised_and_batched_equals_looped(gpdm_prior_model,
                                                                                         walk_07_01):
    from priors.gpdm.prior import GPDMPrior
    from tracker.app.api import prior_entry

    prior = GPDMPrior(gpdm_prior_model, height=HeightOffset(40.0, 2.0))
    known = walk_07_01.poses[:2]
    state = prior.start(known, 4000, np.random.default_rng(5))
    assert np.std(state["height_offset"]) == pytest.approx(40.0, rel=0.05)
    hist = np.repeat(known[None, -1:], 4000, axis=0)
    _, new = prior.sample(hist, 1, state, np.random.default_rng(6))
    assert np.std(new["height_offset"] - state["height_offset"]) == pytest.approx(2.0, rel=0.05)
    weights = np.zeros(4000)
    weights[:2] = 0.5
    assert prior.summarize(new, weights)[0] == pytest.approx(np.mean(new["height_offset"][:2]))
    P = 5  # row by row the same as in one batch
    small = {k: v[:P] for k, v in state.items()}
    noise = prior.step_noise(P, 1, np.random.default_rng(7))
    batched, bstate = prior.advance(hist[:P], 1, small, noise)
    rows = [prior.advance(hist[i:i + 1], 1, {k: v[i:i + 1] for k, v in small.items()}, noise_row(noise, i))
            for i in range(P)]
    assert np.allclose(batched, np.concatenate([r[0] for r in rows]), atol=2e-4)
    assert np.array_equal(bstate["height_offset"], np.concatenate([r[1]["height_offset"] for r in rows]))
    assert GPDMPrior(gpdm_prior_model).part("height").spread == 50.0  # the default
    option = {o.name: o for o in prior_entry("gpdm").options}["height_spread"]
    assert option.default == 50.0 and "(default 50)" in option.described()
    plain = GPDMPrior(gpdm_prior_model, height=HeightOffset(0.0))
    assert "height_offset" not in plain.start(known, 10, np.random.default_rng(0)) and summary_of(plain)[0] == ()
    assert summarize(plain, plain.start(known, 10, np.random.default_rng(0)), np.full(10, 0.1)) is None
    for bad in ((-1.0, 0.0), (0.0, float("nan"))):
        with pytest.raises(InputError, match="height"):
            HeightOffset(*bad)
