"""GPDM core: objective and its gradients, training, mean prediction, save/load, a singular kernel."""
import numpy as np
import pytest
import torch

from priors.gpdm import GPDM, GPDMConfig, load_gpdm, save_gpdm, train_gpdm
from tracker.core.errors import InputError


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
    p = trained.prepare()
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
    a, b = trained.prepare(), loaded.prepare()
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
    from priors.gpdm import train_gpdm_prior
    from tracker.core.body import DOF_NAMES

    return train_gpdm_prior([walk_07_01.poses], GPDMConfig(iterations=100), 60.0, DOF_NAMES, sources=["07_01"])


def test_gpdm_prior_samples_a_batch_of_walking_poses(gpdm_prior_model, walk_07_01):
    from priors.gpdm import GPDMPrior

    prior = GPDMPrior(gpdm_prior_model, root_noise_mm=0.0)
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
    from priors.gpdm import load_gpdm_prior

    gpdm_prior_model.save(tmp_path / "g.pt")
    loaded = load_gpdm_prior(tmp_path / "g.pt")
    assert loaded.fps == 60.0 and loaded.sources == ["07_01"] and np.allclose(loaded.normaliser.mean,
                                                                               gpdm_prior_model.normaliser.mean)
    with pytest.raises(InputError, match="30 fps"):
        loaded.check_compatible("15-cone", loaded.dof_names, 30.0)


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
    assert r.returncode == 2 and "order must be one of 1, 2" in r.stderr.strip().splitlines()[-1]
