"""The motion-prior contract (tracker.engine.prior.MotionPrior), checked for every registered prior.

Every prior the registry knows is built through the public API from small models trained here, and so is a
plugin prior that this file registers through the extension mechanism. Each must:

- sample a batch as it samples each particle alone: a particle's next pose depends on its own history and state
  and on the random numbers at its position in the batch, never on the other particles' histories;
- draw the same poses from the same seed;
- keep histories and state together when the filter reindexes them after resampling;
- continue to the same poses after its state went through a checkpoint file;
- start from the known frames with one row of state per particle, and grow its history from lower orders.

A prior of the package that has no configuration in ``BUILT`` below fails the tests: a new prior joins the
contract by being added there.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from tracker.engine.prior import MotionPrior, label_for, reindex_state

P = 12


class DampedWalkPrior(MotionPrior):
    """The plugin prior of this file: a second-order walk keeping a per-particle damping factor as its state."""

    name = "test-damped-walk"
    order = 2

    def __init__(self, std: np.ndarray):
        self.std = std

    def start(self, known, n_particles, rng):
        return {"damping": rng.uniform(0.2, 0.8, n_particles)}

    def sample(self, history, available, state, rng):
        velocity = history[:, -1] - history[:, -2] if available >= 2 else 0.0
        poses = history[:, -1] + state["damping"][:, None] * velocity
        return poses + self.std * rng.standard_normal(poses.shape), dict(state)

    def diffusion_std(self):
        return self.std


@pytest.fixture(scope="module")
def plugin_prior():
    """``test-damped-walk`` registered through :func:`tracker.engine.registry.register_prior` while the module
    runs, and removed after (other tests list the registered priors)."""
    from tracker.app.plugins import load_plugins
    from tracker.engine.registry import PRIORS, register_prior

    load_plugins()

    @register_prior("test-damped-walk", summary="a damped second-order walk (the contract test's plugin)")
    def build(context, model_files, options):
        return DampedWalkPrior(context.step_std())

    yield "test-damped-walk"
    PRIORS.entries.pop("test-damped-walk", None)


@pytest.fixture(scope="module")
def models(mocap_dir, tmp_path_factory):
    """Small model files of every learned prior, trained once through the API."""
    import tracker

    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("contract_models")
    walks = [mocap_dir / "07" / "07_01.amc", mocap_dir / "02" / "02_01.amc", mocap_dir / "91" / "91_straight_walk.amc"]
    files = {
        "crbm": tracker.train("crbm", walks[:1], order=3, hidden=20, epochs=3, seed=0),
        "crbm-paced": tracker.train("crbm", walks, order=2, hidden=20, epochs=3, seed=1),
        "gpdm": tracker.train("gpdm", walks[:1], iterations=3, seed=2),
        "fcrbm": tracker.train("fcrbm", walks[:2], labels="a,b", order=2, hidden=20, factors=10, features=4,
                               epochs=3, seed=3),
        "deep-crbm": tracker.train("deep-crbm", walks[:1], order=2, hidden=20, epochs=3, top_order=1, top_hidden=10,
                                   top_epochs=3, seed=4),
    }
    paths = {}
    for name, model in files.items():
        paths[name] = out / f"{name}.pt"
        model.save(paths[name])
    return paths


#: How each registered prior is built for the contract: (registered name, model files, options).
BUILT = {
    "zero-velocity": [("zero-velocity", [], {})],
    "constant-velocity": [("constant-velocity", [], {})],
    "crbm": [("crbm", ["crbm"], {}), ("crbm", ["crbm-paced"], {}), ("crbm", ["crbm", "crbm"], {}),
             ("crbm", ["crbm"], {"height_spread": 30.0, "height_drift": 1.0, "posture_gain": 0.2})],
    "gpdm": [("gpdm", ["gpdm"], {}), ("gpdm", ["gpdm"], {"height_drift": 2.0})],
    "fcrbm": [("fcrbm", ["fcrbm"], {}), ("fcrbm", ["fcrbm"], {"style": "b"})],
    "deep-crbm": [("deep-crbm", ["deep-crbm"], {"height_spread": 20.0})],
    "mixture": [("mixture", ["crbm-paced"], {}), ("mixture", ["crbm", "gpdm"], {"components": "crbm,gpdm"}),
                ("mixture", ["fcrbm", "deep-crbm"], {"components": "fcrbm,deep-crbm"}),
                ("mixture", [], {"components": "zero-velocity,constant-velocity", "switch": 0.2})],
    "test-damped-walk": [("test-damped-walk", [], {})],
}
#: Priors without lower orders to grow their history through.
RANDOM_WALKS = ("zero-velocity", "constant-velocity", "test-damped-walk")


def configurations(models, plugin_prior, walk_07_01):
    """Every configuration of :data:`BUILT` as ``(label, prior)``; a registered prior missing from it fails."""
    from tracker.app.api import available_priors, build_prior, prior_entry
    from tracker.core.representation import step_rms

    # The package's priors and this file's plugin (other test files register stubs of their own).
    names = [n for n in available_priors() if prior_entry(n).build.__module__.startswith("priors.")] + [plugin_prior]
    missing = sorted(set(names) - set(BUILT))
    assert not missing, f"registered priors without a contract configuration: {missing}"

    class _Seq:  # what build_prior reads of a sequence
        model = walk_07_01.model
        fps = 60.0
        root = Path("contract")

    out = []
    for name, files, options in [c for n in names for c in BUILT[n]]:
        prior = build_prior(name, _Seq(), [models[f] for f in files], step_std=step_rms([walk_07_01.poses]),
                            **options)
        out.append((f"{name} {'+'.join(files)} {options}", prior))
    return out


@pytest.fixture(scope="module")
def priors(models, plugin_prior, walk_07_01):
    return configurations(models, plugin_prior, walk_07_01)


def rollout(prior, poses: np.ndarray, n_particles: int, seed: int, frames: int):
    """``frames`` steps of ``prior`` from the known frames ``poses[:order]``: the histories ``P x N x D``, the
    available count and the state before the last step."""
    rng = np.random.default_rng(seed)
    known = poses[:prior.order]
    state = prior.start(known, n_particles, rng)
    history = np.repeat(known[None], n_particles, axis=0)
    available = prior.order
    for _ in range(frames):
        new, state = prior.sample(history, available, state, rng)
        history = np.concatenate([history[:, 1:], new[:, None]], axis=1)
    return history, available, state


def rows(state, n: int):
    """Every array of a (nested) state, to check that each has one row per particle."""
    if state is None:
        return
    if isinstance(state, dict):
        for v in state.values():
            yield from rows(v, n)
    else:
        yield np.asarray(state)


def test_every_registered_prior_starts_with_one_state_row_per_particle(priors, walk_07_01):
    for label, prior in priors:
        state = prior.start(walk_07_01.poses[:prior.order], P, np.random.default_rng(0))
        for array in rows(state, P):
            assert array.shape[:1] == (P,), label


def test_the_same_seed_draws_the_same_poses(priors, walk_07_01):
    for label, prior in priors:
        a = rollout(prior, walk_07_01.poses, P, 3, 3)[0]
        b = rollout(prior, walk_07_01.poses, P, 3, 3)[0]
        assert np.array_equal(a, b), label
        c = rollout(prior, walk_07_01.poses, P, 4, 3)[0]
        assert not np.array_equal(a, c), label


def shared_frames(prior) -> int:
    """Frames to roll out before a batch check: 2, or 0 for a prior with a posture offset. That offset is one for
    the whole particle set (it integrates the posterior's mean posture correction, :class:`priors.parts.
    PostureOffset`), the one part that sees the other particles by design; before its first move it sees none."""
    members = getattr(prior, "members", None) or getattr(prior, "components", None) or [prior]
    return 0 if any(getattr(m, "posture", None) is not None for m in members) else 2


def test_a_batch_samples_each_particle_as_it_would_alone(priors, walk_07_01):
    """Row ``i`` of a batch is the same whatever the other rows' histories: replacing every other particle's
    history by particle ``i``'s (as sampling it alone would) leaves its pose unchanged."""
    for label, prior in priors:
        history, available, state = rollout(prior, walk_07_01.poses, P, 5, shared_frames(prior))
        batched = prior.sample(history, available, state, np.random.default_rng(9))[0]
        for i in (0, P // 2, P - 1):
            alone = np.repeat(history[i:i + 1], P, axis=0)
            looped = prior.sample(alone, available, state, np.random.default_rng(9))[0]
            assert np.allclose(looped[i], batched[i], rtol=1e-5, atol=1e-4), (label, i)


def groups(state) -> np.ndarray | None:
    """The component each particle belongs to where a prior keeps components apart (an ensemble's member, an
    FCRBM's style label, a mixture's motion model): resampling within a component leaves every component's random numbers where they were."""
    if isinstance(state, dict):
        for key in ("style", "component"):
            if key in state:
                return np.asarray(state[key])
    return None


def test_reindexing_after_resampling_keeps_histories_and_state_together(priors, walk_07_01):
    """After resampling picked particle ``i`` for every slot of its component, slot ``i`` samples what particle
    ``i`` would have."""
    for label, prior in priors:
        history, available, state = rollout(prior, walk_07_01.poses, P, 6, shared_frames(prior))
        batched = prior.sample(history, available, state, np.random.default_rng(11))[0]
        for i in (1, P - 2):
            component = groups(state)
            idx = np.full(P, i) if component is None else np.where(component == component[i], i, np.arange(P))
            picked = prior.reindex(state, idx)
            for array, original in zip(rows(picked, P), rows(reindex_state(state, idx), P)):
                assert np.array_equal(array, original, equal_nan=True), label
            again = prior.sample(history[idx], available, picked, np.random.default_rng(11))[0]
            assert np.allclose(again[i], batched[i], rtol=1e-5, atol=1e-4), (label, i)


def test_a_checkpointed_state_continues_to_the_same_poses(priors, walk_07_01, tmp_path):
    from tracker.app.checkpoint import load_checkpoint, save_checkpoint
    from tracker.engine.filter import FilterState
    from tracker.engine.recording import Recording
    from tracker.engine.weights import LogWeights

    for k, (label, prior) in enumerate(priors):
        history, available, state = rollout(prior, walk_07_01.poses, P, 7, 2)
        rng = np.random.default_rng(13)
        path = tmp_path / f"checkpoint{k}.npz"
        filter_state = FilterState(history, state, LogWeights(np.zeros(P)), history[0], available, 2)
        save_checkpoint(path, filter_state, Recording(()), rng.bit_generator.state, {"prior": label})
        direct = prior.sample(history, available, state, rng)[0]
        resumed_rng = np.random.default_rng(0)
        restored, _ = load_checkpoint(path, {"prior": label}, Recording(()), resumed_rng)
        resumed = prior.sample(restored.history, restored.available, restored.prior_state, resumed_rng)[0]
        assert np.array_equal(direct, resumed), label


def test_a_learned_prior_grows_its_history_from_one_known_frame(priors, walk_07_01):
    """From one known pose the history grows through the lower orders the model files carry (Taylor 2009,
    Sec. 6.4): every step draws finite poses and says which model drew them."""
    for label, prior in priors:
        parts = getattr(prior, "components", [prior])
        if prior.order < 2 or all(p.name in RANDOM_WALKS for p in parts):
            continue  # a random walk has no lower orders: it samples from whatever history it has
        rng = np.random.default_rng(8)
        known = walk_07_01.poses[:1]
        state = prior.start(known, P, rng)
        history = np.repeat(walk_07_01.poses[None, :1], prior.order, axis=1).repeat(P, axis=0)
        labels = []
        for available in range(1, prior.order + 1):
            labels.append(label_for(prior, available))
            new, state = prior.sample(history, available, state, rng)
            assert np.all(np.isfinite(new)), (label, available)
            history = np.concatenate([history[:, 1:], new[:, None]], axis=1)
        assert labels[0] != labels[-1], label


def test_model_files_of_0_13_sample_as_they_did(walk_07_01):
    """A paced CRBM-3 and a GPDM saved by pose-tracker 0.13.0 (tests/data) load, and at their defaults draw, from
    the same seed, the poses 0.13.0 drew (``samples_v0.13.npy``: 4 steps of 8 particles from 07_01's first
    frames; the defaults' numbers did not change when the priors became a model plus parts)."""
    from tracker.app.api import build_prior

    data = Path(__file__).parent / "data"
    expected = np.load(data / "samples_v0.13.npy")

    class _Seq:
        model, fps, root = walk_07_01.model, 60.0, Path("v0.13")

    for k, (name, file) in enumerate((("crbm", "crbm3_paced_v0.13.pt"), ("gpdm", "gpdm_v0.13.pt"))):
        prior = build_prior(name, _Seq(), [data / file])
        rng = np.random.default_rng(5)
        known = walk_07_01.poses[:3]
        state = prior.start(known, 8, rng)
        history = np.repeat(known[None, -prior.order:], 8, axis=0)
        for step in range(4):
            poses, state = prior.sample(history, prior.order, state, rng)
            history = np.concatenate([history[:, 1:], poses[:, None]], axis=1)
            assert np.allclose(poses, expected[k, step], rtol=0, atol=1e-6), (name, step)
            idx = np.arange(8) // 2 * 2  # resampling: the even particles twice (the posture offset moves)
            history, state = history[idx], prior.reindex(state, idx)
