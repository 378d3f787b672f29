"""The likelihood's torch path (``--device``): the same kinematics, projection and lookups as the CPU path, on
torch tensors. These tests run it on ``device="cpu"`` (and on CUDA where a GPU is present) against the same array
code on numpy arrays and against the compiled CPU path, which stays the CPU default because it is faster there."""
from __future__ import annotations

import numpy as np
import pytest
import torch

import likelihoods.edge_silhouette as edge_silhouette
from likelihoods.edge_silhouette import EdgeSilhouetteConfig, EdgeSilhouetteLikelihood
from tracker.app.api import build_likelihood, track
from tracker.core.body import fifteen_cone_model
from tracker.core.errors import InputError
from tracker.core.kinematics import forward_kinematics
from tracker.core.torch_kinematics import exp_map_to_matrix_torch, torch_kinematics
from tracker.core.rotations import exp_map_to_matrix

DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


def _random_poses(model, rng, n: int) -> np.ndarray:
    lower = np.maximum(model.lower, -3.0)
    upper = np.minimum(model.upper, 3.0)
    poses = rng.uniform(lower, upper, (n, model.n_dofs))
    poses[:, :3] = rng.normal(0.0, 800.0, (n, 3))
    return poses


def _around(truth: np.ndarray, rng, n: int, scale: float = 0.05) -> np.ndarray:
    """Poses scattered around ``truth`` (50 mm on the root position, 0.05 rad on every angle at scale 0.05)."""
    spread = np.r_[[1000.0 * scale] * 3, [scale] * (truth.size - 3)]
    return truth + rng.standard_normal((n, truth.size)) * spread


@pytest.mark.parametrize("device", DEVICES)
def test_exp_maps_match_the_cpu_rotations_also_near_zero(device, rng):
    v = np.concatenate([rng.normal(0, 2, (200, 3)), rng.normal(0, 1e-8, (20, 3)), np.zeros((1, 3))])
    got = exp_map_to_matrix_torch(torch.as_tensor(v, device=device)).cpu().numpy()
    np.testing.assert_allclose(got, exp_map_to_matrix(v), atol=1e-12)


@pytest.mark.parametrize("device", DEVICES)
def test_small_matmul_is_the_matrix_product_for_every_shape_the_kinematics_uses(device, rng):
    from tracker.core.torch_kinematics import small_matmul

    def t(*shape):
        return torch.as_tensor(rng.normal(size=shape), device=device)

    for a, b in ((t(7, 4, 3, 3), t(7, 4, 3, 3)), (t(4, 3, 3), t(7, 4, 3, 3)), (t(7, 4, 3, 3), t(4, 3, 1)),
                 (t(7, 15, 3, 3), t(15, 3, 3))):
        np.testing.assert_allclose(small_matmul(a, b).cpu().numpy(), (a @ b).cpu().numpy(), atol=1e-12)
    with pytest.raises(ValueError, match="do not multiply"):
        small_matmul(t(2, 3, 3), t(2, 2, 3))


@pytest.mark.parametrize("device", DEVICES)
def test_torch_kinematics_equal_the_compiled_kinematics(device, rng, bodytrack_dir):
    from data_tools.sequences.bodytrack import bodytrack_model

    for model in (fifteen_cone_model(), bodytrack_model(bodytrack_dir)[0]):
        poses = _random_poses(model, rng, 300)
        R, o = forward_kinematics(model, poses).segment_rotations()
        Rt, ot = torch_kinematics(model, device)(torch.as_tensor(poses, device=device))
        np.testing.assert_allclose(Rt.cpu().numpy(), R, atol=1e-12)
        np.testing.assert_allclose(ot.cpu().numpy(), o, atol=1e-9)  # mm


@pytest.fixture(autouse=True)
def one_torch_thread():
    """Torch on one thread for these tests (restored after), so a busy machine does not slow them tenfold."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.mark.parametrize("bidirectional", [False, True])
@pytest.mark.parametrize("device", DEVICES)
def test_device_likelihood_equals_the_cpu_path(walk_32_frames, rng, device, bidirectional, monkeypatch):
    monkeypatch.setattr(edge_silhouette, "DEVICE_BLOCK", 256)  # several blocks on the device too
    monkeypatch.setattr(edge_silhouette, "DEVICE_BLOCK_BIDIRECTIONAL", 256)
    seq = walk_32_frames
    k = 12
    truth = seq.groundtruth.poses[k]
    poses = np.concatenate([_around(truth, rng, 600), _random_poses(seq.model, rng, 50),
                            truth[None] + np.r_[[0.0] * 6, [9.0] * (truth.size - 6)]])  # the last outside the limits
    poses[-2, :3] = seq.rig[0].centre - 3000.0 * seq.rig[0].R[2]  # 3 m behind camera 0: every cone reads cost 1
    config = EdgeSilhouetteConfig(bidirectional=bidirectional)
    frame = seq.frame(k, range(4))
    compiled = EdgeSilhouetteLikelihood(seq.model, seq.rig, config)
    cpu = compiled.prepare(frame).terms(poses)
    dev = EdgeSilhouetteLikelihood(seq.model, seq.rig, config, device=device).prepare(frame).terms(poses)
    assert np.isneginf(cpu.log_likelihood[-1]) and np.isneginf(dev.log_likelihood[-1])
    assert np.all(cpu.edge[-2, 0] == 1.0) and np.all(dev.edge[-2, 0] == 1.0)  # every cone behind camera 0
    ok = np.isfinite(cpu.log_likelihood)
    assert np.array_equal(ok, np.isfinite(dev.log_likelihood))
    # The same array code on numpy arrays, float32 from the camera frames on as on the device: a different
    # summation order moves pixels by ~1e-5 px (a point on a pixel boundary may round the other way: at most
    # sharpness / points per view per flip). The compiled CPU path computes in float64: more such flips.
    edge, sil, cover = compiled.array_costs(poses[ok], compiled.prepare(frame).maps)
    numpy32 = -config.sharpness * (edge + sil + (0.0 if cover is None else cover)).sum(axis=1)
    for reference, share in ((numpy32, 0.99), (cpu.log_likelihood[ok], 0.95)):
        close = np.abs(dev.log_likelihood[ok] - reference) < 1e-3
        assert close.mean() > share
        np.testing.assert_allclose(dev.log_likelihood[ok], reference, atol=0.5)
    for name in ("edge", "silhouette") + (("coverage",) if bidirectional else ()):
        difference = np.abs(getattr(dev, name) - getattr(cpu, name))  # costs in [0, 1], P x V
        assert (difference < 1e-4).mean() > 0.98 and difference.max() < 0.02, name


@pytest.mark.slow
@pytest.mark.parametrize("device", DEVICES)
def test_tracking_on_the_device_path_gives_the_cpu_errors(walk_32_frames, random_walk_std, device):
    """The first frame's estimate is the same to 0.01 mm; after a resampling step a weight that differs in the
    fifth decimal (float32 on the device, float64 on the CPU) picks other particles, so the runs part: the same
    accuracy, another sequence of particles."""
    seq = walk_32_frames
    runs = {}
    for name, lik_device in (("cpu path", None), ("torch path", device)):
        likelihood = EdgeSilhouetteLikelihood(seq.model, seq.rig, device=lik_device)
        runs[name] = track(seq, "zero-velocity", likelihood=likelihood, particles=300, frames=10, seed=4,
                           step_std=random_walk_std)
    cpu, dev = runs["cpu path"].errors, runs["torch path"].errors  # mm
    assert abs(dev[0] - cpu[0]) < 0.01
    assert abs(dev.mean() - cpu.mean()) < 0.25 * cpu.mean()


@pytest.mark.parametrize("device", DEVICES)
def test_impossible_poses_and_empty_batches_on_the_device(walk_32_frames, device):
    seq = walk_32_frames
    scorer = EdgeSilhouetteLikelihood(seq.model, seq.rig, device=device).prepare(seq.frame(3, range(4)))
    cpu = EdgeSilhouetteLikelihood(seq.model, seq.rig).prepare(seq.frame(3, range(4)))
    truth = seq.groundtruth.poses[3]
    poses = np.repeat(truth[None], 4, axis=0)
    poses[1, 7] = np.nan
    poses[2, 0] = np.inf  # the root position's limits are infinite: still no pose
    poses[3, 1] = -np.inf
    for s in (scorer, cpu):
        ll = s(poses)
        assert np.isfinite(ll[0]) and np.all(np.isneginf(ll[1:]))
        assert s(poses[:0]).shape == (0,)
    terms = scorer.terms(poses[:0])
    assert terms.edge.shape == (0, 4) and terms.log_likelihood.shape == (0,)


def test_bad_devices_are_one_line_errors(walk_32_frames):
    cases = [("gpu0", "unknown device 'gpu0'; use cpu, cuda or cuda:N"), ("meta", "not supported")]
    if not torch.cuda.is_available():
        cases.append(("cuda", "no CUDA device"))
    for name, expected in cases:
        with pytest.raises(InputError, match=expected) as err:
            build_likelihood("edge-silhouette", walk_32_frames, device=name)
        assert "\n" not in str(err.value)


def test_the_device_is_recorded_and_cpu_keeps_the_numpy_path(walk_32_frames):
    assert build_likelihood("edge-silhouette", walk_32_frames).device is None
    assert build_likelihood("edge-silhouette", walk_32_frames, device="cpu:0").device is None
    lik = EdgeSilhouetteLikelihood(walk_32_frames.model, walk_32_frames.rig, device="cpu")
    assert lik.settings()["device"] == "cpu"
