"""The motion-prior contract (:class:`tracker.engine.prior.MotionPrior`) as a base class of tests.

A subclass fills :meth:`PriorContract.make_prior` and :meth:`PriorContract.known_poses`; every ``test_*``
method then checks the prior through its public interface only:

- it starts from the known frames with one row of state per particle, samples ``P x D`` finite poses, and
  states its settings and diffusion as plain numbers;
- it samples a batch as it samples each particle alone: a particle's next pose depends on its own history and
  state and on the random numbers at its position in the batch, never on the other particles' histories;
- it draws the same poses from the same seed, and others from another;
- it keeps histories and state together when the filter reindexes them after resampling;
- it continues to the same poses after its state went through a checkpoint file;
- from one known frame, it draws finite poses while its history grows (through lower orders, where it has
  them: Taylor 2009, Sec. 6.4);
- each of its parts (:meth:`PriorContract.parts`) states its settings among the prior's.

Shapes: known poses ``T x D``; histories ``P x N x D`` (oldest first); poses ``P x D``; mm and radians.
"""
from __future__ import annotations

import json
from typing import Any, Iterator, Sequence

import numpy as np

from tracker.engine.mixture import mixing_of
from tracker.engine.prior import MotionPrior, PriorState, label_for, reindex_state


def rollout(prior: MotionPrior, poses: np.ndarray, n_particles: int, seed: int,
            frames: int) -> tuple[np.ndarray, int, PriorState]:
    """``frames`` steps of ``prior`` from the known frames ``poses[:order]`` with a generator seeded ``seed``:
    the histories ``P x N x D``, the available count and the state before the next step."""
    rng = np.random.default_rng(seed)
    known = poses[:prior.order]
    state = prior.start(known, n_particles, rng)
    history = np.repeat(known[None], n_particles, axis=0)
    available = prior.order
    for _ in range(frames):
        new, state = prior.sample(history, available, state, rng)
        history = np.concatenate([history[:, 1:], new[:, None]], axis=1)
    return history, available, state


def state_arrays(state: PriorState) -> Iterator[np.ndarray]:
    """Every array of a (nested) per-particle state, in a fixed order."""
    if state is None:
        return
    if isinstance(state, dict):
        for key in sorted(state):
            yield from state_arrays(state[key])
    else:
        yield np.asarray(state)


class PriorContract:
    """Checks a motion prior against the contract the particle filter relies on.

    Subclass it in a test module (as ``TestMyPrior(PriorContract)``) and fill :meth:`make_prior` and
    :meth:`known_poses`; override the other hooks where the defaults do not describe the prior. Every check
    uses :attr:`particles` particles and its own seeds.
    """

    #: Particles in each check.
    particles: int = 12
    #: How far a particle's pose drawn in a batch may be from the one drawn alone (mm or radians): torch's
    #: batched matrix products may sum in another order than a batch of one.
    batch_tolerance: float = 1e-4

    # --- what a subclass provides ---------------------------------------------------------------------

    def make_prior(self) -> MotionPrior:
        """The prior to check (built as a user would: through its registered builder, or directly)."""
        raise NotImplementedError(f"{type(self).__name__} must implement make_prior() -> MotionPrior")

    def known_poses(self) -> np.ndarray:
        """Poses ``T x D`` of real motion the prior is started from (``T`` at least the prior's order): the
        known frames of a tracking run."""
        raise NotImplementedError(f"{type(self).__name__} must implement known_poses() -> T x D poses")

    def components(self, prior: MotionPrior, state: PriorState) -> np.ndarray | None:
        """Each particle's component ``(P,)`` where the prior keeps groups of particles apart, each sampled
        with its own stream of random numbers (resampling within a group leaves every group's draws where
        they were); None where it samples the whole batch at once. Default: the components the prior keeps
        apart (:class:`~tracker.engine.mixture.ComponentPrior`)."""
        return None if mixing_of(prior) is None else np.asarray(prior.component_of(state))

    def frames_before_batch_check(self, prior: MotionPrior) -> int:
        """Steps to roll out before the batch and reindexing checks (2). A prior with a part that by design
        sees the whole particle set (e.g. a posture offset integrating the posterior's mean correction) returns
        0: before its first move that part sees none of the other particles."""
        return 2

    def grows_history(self, prior: MotionPrior) -> bool:
        """Whether the prior draws with lower orders while its history grows from one known frame (a learned
        prior whose model files carry them), so that the model named by ``label_for`` changes on the way; a
        random walk samples from whatever history it has (False, the default)."""
        return False

    def parts(self, prior: MotionPrior) -> Sequence[Any]:
        """The per-particle parts of the prior to check one by one (ground diffusion, pace, root height,
        posture, ...): each has ``settings() -> dict``. None by default."""
        return ()

    # --- the contract ---------------------------------------------------------------------------------

    def _prior_and_poses(self) -> tuple[MotionPrior, np.ndarray]:
        prior = self.make_prior()
        poses = np.asarray(self.known_poses(), float)
        assert poses.ndim == 2 and len(poses) >= prior.order, \
            f"known_poses() must give at least order ({prior.order}) poses T x D, got {poses.shape}"
        return prior, poses

    def test_starts_with_one_state_row_per_particle_and_samples_one_pose_each(self):
        prior, poses = self._prior_and_poses()
        P, D = self.particles, poses.shape[1]
        rng = np.random.default_rng(0)
        state = prior.start(poses[:prior.order], P, rng)
        for array in state_arrays(state):
            assert array.shape[:1] == (P,), f"a state array of shape {array.shape} for {P} particles"
        history = np.repeat(poses[None, :prior.order], P, axis=0)
        new, after = prior.sample(history, prior.order, state, rng)
        assert isinstance(new, np.ndarray) and new.shape == (P, D), f"sample gave {np.shape(new)}, not {(P, D)}"
        assert np.all(np.isfinite(new))
        for array in state_arrays(after):
            assert array.shape[:1] == (P,), f"a state array of shape {array.shape} for {P} particles after a step"

    def test_states_its_diffusion_and_settings_as_plain_numbers(self):
        prior, poses = self._prior_and_poses()
        std = np.asarray(prior.diffusion_std(), float)
        assert std.shape == (poses.shape[1],) and np.all(np.isfinite(std)) and np.all(std >= 0), std
        settings = prior.settings()
        assert isinstance(settings, dict)
        json.dumps(settings)  # written to result.json as it is: plain JSON values only
        assert isinstance(label_for(prior, prior.order), str) and prior.name

    def test_the_same_seed_draws_the_same_poses(self):
        prior, poses = self._prior_and_poses()
        a = rollout(prior, poses, self.particles, 3, 3)[0]
        b = rollout(prior, poses, self.particles, 3, 3)[0]
        assert np.array_equal(a, b), "the same seed drew other poses"
        c = rollout(prior, poses, self.particles, 4, 3)[0]
        assert not np.array_equal(a, c), "another seed drew the same poses"

    def test_a_batch_samples_each_particle_as_it_would_alone(self):
        """Row ``i`` of a batch is the same whatever the other rows' histories: replacing every other
        particle's history by particle ``i``'s (as sampling it alone would) leaves its pose unchanged."""
        prior, poses = self._prior_and_poses()
        P = self.particles
        history, available, state = rollout(prior, poses, P, 5, self.frames_before_batch_check(prior))
        batched = prior.sample(history, available, state, np.random.default_rng(9))[0]
        for i in (0, P // 2, P - 1):
            alone = np.repeat(history[i:i + 1], P, axis=0)
            looped = prior.sample(alone, available, state, np.random.default_rng(9))[0]
            np.testing.assert_allclose(looped[i], batched[i], rtol=1e-5, atol=self.batch_tolerance,
                                       err_msg=f"particle {i} drew another pose beside other histories")

    def test_reindexing_after_resampling_keeps_histories_and_state_together(self):
        """After resampling picked particle ``i`` for every slot of its component, slot ``i`` samples what
        particle ``i`` would have, and the prior's reindexed state holds the rows it was picked from."""
        prior, poses = self._prior_and_poses()
        P = self.particles
        history, available, state = rollout(prior, poses, P, 6, self.frames_before_batch_check(prior))
        batched = prior.sample(history, available, state, np.random.default_rng(11))[0]
        component = self.components(prior, state)
        for i in (1, P - 2):
            idx = np.full(P, i) if component is None else np.where(component == component[i], i, np.arange(P))
            picked = prior.reindex(state, idx)
            for array, original in zip(state_arrays(picked), state_arrays(reindex_state(state, idx))):
                assert np.array_equal(array, original, equal_nan=True), "reindexed state is not the picked rows"
            again = prior.sample(history[idx], available, picked, np.random.default_rng(11))[0]
            np.testing.assert_allclose(again[i], batched[i], rtol=1e-5, atol=self.batch_tolerance,
                                       err_msg=f"particle {i} drew another pose after reindexing")

    def test_a_checkpointed_state_continues_to_the_same_poses(self, tmp_path):
        from tracker.app.checkpoint import load_checkpoint, save_checkpoint
        from tracker.engine.filter import FilterState
        from tracker.engine.recording import Recording
        from tracker.engine.weights import LogWeights

        prior, poses = self._prior_and_poses()
        P = self.particles
        history, available, state = rollout(prior, poses, P, 7, 2)
        rng = np.random.default_rng(13)
        path = tmp_path / "checkpoint.npz"
        fingerprint = {"prior": prior.name}
        save_checkpoint(path, FilterState(history, state, LogWeights(np.zeros(P)), history[0], available, 2),
                        Recording(()), rng.bit_generator.state, fingerprint)
        direct = prior.sample(history, available, state, rng)[0]
        resumed_rng = np.random.default_rng(0)
        restored, _ = load_checkpoint(path, fingerprint, Recording(()), resumed_rng)
        resumed = prior.sample(restored.history, restored.available, restored.prior_state, resumed_rng)[0]
        assert np.array_equal(direct, resumed), "the restored state drew other poses"

    def test_grows_its_history_from_one_known_frame(self):
        """From one known pose (older history slots repeat it) every step draws finite poses; a prior that
        grows its history through lower orders names another model at the first step than at the last."""
        prior, poses = self._prior_and_poses()
        P = self.particles
        if prior.order < 2:
            import pytest

            pytest.skip(f"{prior.name} is of order 1: its history never grows")
        rng = np.random.default_rng(8)
        state = prior.start(poses[:1], P, rng)
        history = np.repeat(poses[None, :1], prior.order, axis=1).repeat(P, axis=0)
        labels = []
        for available in range(1, prior.order + 1):
            labels.append(label_for(prior, available))
            new, state = prior.sample(history, available, state, rng)
            assert np.all(np.isfinite(new)), f"non-finite poses with {available} known frames"
            history = np.concatenate([history[:, 1:], new[:, None]], axis=1)
        if self.grows_history(prior):
            assert labels[0] != labels[-1], f"the same model ({labels[0]}) drew with 1 and {prior.order} frames"

    def test_each_part_states_its_settings_among_the_priors(self):
        prior, _ = self._prior_and_poses()
        settings = prior.settings()
        for part in self.parts(prior):
            own = part.settings()
            json.dumps(own)
            for key, value in own.items():
                assert settings.get(key) == value, f"the prior's settings lack {type(part).__name__}'s {key}"
