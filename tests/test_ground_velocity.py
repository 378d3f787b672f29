"""The learned priors' ``ground_velocity_noise``: each particle keeps its own ground step (constant velocity in the
body's frame, with noise) while the model drives the body, and a paced model is told the particle's own speed."""
import numpy as np
import pytest
import torch

from priors.common import persist_ground_step
from priors.crbm import CRBMConfig, CRBMPrior, train_crbm
from priors.deep_crbm import DeepCRBMPrior  # noqa: F401  (registers the deep-crbm prior)
from priors.fcrbm import FCRBMConfig, FCRBMPrior, train_fcrbm
from tracker.core.body import DOF_NAMES
from tracker.core.errors import InputError
from tracker.core.representation import STANDING_LOG_PACE, log_pace, pending_step, poses_to_invariant
from tracker.engine.registry import PRIORS


@pytest.fixture(scope="module")
def poses_07_01(walk_07_01):
    torch.set_num_threads(1)
    return walk_07_01.poses


@pytest.fixture(scope="module")
def plain(poses_07_01):
    return train_crbm([poses_07_01], CRBMConfig(order=1, hidden=20, epochs=5), 60.0, DOF_NAMES,
                      rng=np.random.default_rng(0))


@pytest.fixture(scope="module")
def paced(poses_07_01):
    slow = poses_07_01.copy()
    slow[:, :2] = slow[0, :2] + 0.5 * (slow[:, :2] - slow[0, :2])  # the same gait at half the ground speed
    return train_crbm([poses_07_01, slow], CRBMConfig(order=1, hidden=20, epochs=5, pace_input=True), 60.0,
                      DOF_NAMES, rng=np.random.default_rng(0))


def roll_out(prior: CRBMPrior, known: np.ndarray, n: int, frames: int, seed: int) -> np.ndarray:
    """``n`` particles sampled ``frames`` frames on from the known poses: ``n x (2 + frames) x D``."""
    rng = np.random.default_rng(seed)
    history = np.repeat(known[None, -2:], n, axis=0)
    state = prior.start(known, n, rng)
    for _ in range(frames):
        poses, state = prior.sample(history[:, -prior.order:], prior.order, state, rng)
        history = np.concatenate([history, poses[:, None]], axis=1)
    return history


def assert_steps_decay(prior, known: np.ndarray, frames: int, kept: float) -> None:
    """Without noise, every particle's ground steps after ``known`` are the known frames' step times
    ``kept ** k`` at the k-th tracked frame (``kept`` = 1 - pull)."""
    expected = pending_step(known)[:2]
    steps = poses_to_invariant(roll_out(prior, known, 3, frames, seed=1))[:, 1:-1, :2]
    assert np.allclose(steps, expected * kept ** np.arange(steps.shape[1])[None, :, None], atol=1e-6)


def test_without_noise_each_particle_keeps_the_known_frames_ground_step(plain, poses_07_01):
    known = poses_07_01[58:60]
    expected = pending_step(known)[:2]  # forward, lateral (mm/frame) out of the last known pose
    held = roll_out(CRBMPrior([plain], root_noise_mm=0.0, ground_velocity_noise=0.0), known, 6, 30, seed=1)
    steps = poses_to_invariant(held)[:, 1:-1, :2]  # every step taken after the known frames
    assert np.allclose(steps, expected, atol=1e-6)
    # The model's own steps are not constant (the check above can fail): without the option they vary.
    learned = roll_out(CRBMPrior([plain], root_noise_mm=0.0), known, 6, 30, seed=1)
    assert np.abs(poses_to_invariant(learned)[:, 2:-1, :2] - expected).max() > 1.0
    # The body still moves as the model says: the joints of both runs are the model's samples, not the history.
    assert np.abs(held[:, -1, 6:] - known[-1, 6:]).max() > 0.05


def test_the_step_changes_by_the_noise_given(plain, poses_07_01):
    rng = np.random.default_rng(2)
    step = np.tile([20.0, -3.0, 0.01], (20000, 1))
    out = persist_ground_step(step, 0.7, rng)
    assert out.shape == (20000, 2)
    assert np.mean(out, axis=0) == pytest.approx([20.0, -3.0], abs=0.02)
    assert np.std(out, axis=0) == pytest.approx([0.7, 0.7], rel=0.03)
    prior = CRBMPrior([plain], ground_velocity_noise=0.7)
    known = poses_07_01[58:60]
    state = prior.start(known, 5000, rng)
    _, after = prior.sample(np.repeat(known[None, -1:], 5000, axis=0), 1, state, rng)
    assert np.std(after["step"][:, :2] - state["step"][:, :2], axis=0) == pytest.approx([0.7, 0.7], rel=0.05)


def test_a_paced_model_is_told_the_particles_own_speed(paced, poses_07_01):
    prior = CRBMPrior([paced], ground_velocity_noise=1.0, root_noise_mm=0.0)
    rng = np.random.default_rng(3)
    known = poses_07_01[58:60]
    state = prior.start(known, 200, rng)
    state["step"][:100, :2] = 0.0  # half the particles stand still
    _, after = prior.sample(np.repeat(known[None, -1:], 200, axis=0), 1, state, rng)
    assert np.allclose(after["pace"], np.maximum(log_pace(state["step"]), STANDING_LOG_PACE))
    assert np.allclose(after["pace"][:100], STANDING_LOG_PACE)
    assert after["pace"][100:].min() > STANDING_LOG_PACE + 1.0


def test_bad_settings_are_refused(plain, paced):
    with pytest.raises(InputError, match="ground velocity noise"):
        CRBMPrior([plain], ground_velocity_noise=-1.0)
    with pytest.raises(InputError, match="pace jump"):  # a jump would set a pace the particle does not walk at
        CRBMPrior([paced], ground_velocity_noise=0.5, pace_jump=0.1)
    assert CRBMPrior([plain]).settings()["ground_velocity_noise_mm"] is None  # off by default


def test_the_fcrbm_keeps_each_particles_own_step_too(poses_07_01):
    slow = poses_07_01.copy()
    slow[:, :2] = slow[0, :2] + 0.5 * (slow[:, :2] - slow[0, :2])
    model = train_fcrbm([poses_07_01, slow], ["walk", "slow walk"],
                        FCRBMConfig(order=1, hidden=12, factors=6, features=3, epochs=3), 60.0, DOF_NAMES,
                        rng=np.random.default_rng(0))
    assert_steps_decay(FCRBMPrior([model], root_noise_mm=0.0, ground_velocity_noise=0.0, ground_velocity_pull=0.5),
                       poses_07_01[58:60], 8, 0.5)
    with pytest.raises(InputError, match="with ground velocity noise"):
        FCRBMPrior([model], ground_velocity_pull=0.5)


def test_the_crbm_family_declares_the_options():
    for name in ("crbm", "deep-crbm", "fcrbm"):
        options = {o.name: o for o in PRIORS.get(name).options}
        assert options["ground_velocity_noise"].default is None
        assert options["ground_velocity_noise"].flag == "--ground-velocity-noise"
        assert options["ground_velocity_pull"].default == 0.0
        assert options["ground_velocity_pull"].flag == "--ground-velocity-pull"


def test_a_pull_decays_the_velocity_toward_standing_still(plain, poses_07_01):
    step = np.tile([20.0, -4.0, 0.01], (4, 1))
    assert np.allclose(persist_ground_step(step, 0.0, np.random.default_rng(0), pull=0.25), [[15.0, -3.0]] * 4)
    # Without noise the velocity falls geometrically from the known frames' step toward zero.
    assert_steps_decay(CRBMPrior([plain], root_noise_mm=0.0, ground_velocity_noise=0.0, ground_velocity_pull=0.1),
                       poses_07_01[58:60], 30, 0.9)
    # With noise the velocity stays bounded: its std settles at std / sqrt(1 - (1 - pull)^2), not sqrt(t) * std.
    rng = np.random.default_rng(4)
    v = np.zeros((20000, 3))
    for _ in range(200):
        v[:, :2] = persist_ground_step(v, 1.0, rng, pull=0.1)
    assert np.std(v[:, :2], axis=0) == pytest.approx([1 / np.sqrt(1 - 0.9 ** 2)] * 2, rel=0.03)


def test_a_pull_without_own_velocity_or_out_of_range_is_refused(plain):
    with pytest.raises(InputError, match="with ground velocity noise"):
        CRBMPrior([plain], ground_velocity_pull=0.1)
    with pytest.raises(InputError, match="fraction per frame"):
        CRBMPrior([plain], ground_velocity_noise=0.5, ground_velocity_pull=1.5)
    assert CRBMPrior([plain], ground_velocity_noise=0.5, ground_velocity_pull=0.1).settings()[
        "ground_velocity_pull"] == 0.1
