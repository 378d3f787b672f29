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
- each of its parts (:meth:`PriorContract.parts`, :class:`priors.parts.Part`) is checked through the part
  protocol: it starts the state entries it declares (:attr:`~priors.parts.Part.KEYS`) with one row per particle
  from the known frames, and the prior's state carries them; reindexing after resampling picks their rows; they
  come back from a checkpoint file as they were; its summary is a finite number the prior reports under the
  part's name; its settings are its options' values under the options' names, among the prior's; and it draws
  its random numbers from the generator passed in only, one row per particle.

Shapes: known poses ``T x D``; histories ``P x N x D`` (oldest first); poses ``P x D``; mm and radians.
"""
from __future__ import annotations

import json
from typing import Any, Iterator, Sequence

import numpy as np

from priors.parts import Part
from tracker.engine.multiple_models import mixing_of
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


def checkpointed(prior: MotionPrior, history: np.ndarray, available: int, state: PriorState,
                 rng: np.random.Generator, folder) -> tuple[Any, np.random.Generator]:
    """``state`` (with ``history`` ``P x N x D`` and ``available``) and ``rng`` written to a filter checkpoint in
    ``folder`` and read back: the restored filter state (:class:`~tracker.engine.filter.FilterState`) and a
    generator in the saved state."""
    from tracker.app.checkpoint import load_checkpoint, save_checkpoint
    from tracker.engine.filter import FilterState
    from tracker.engine.recording import Recording
    from tracker.engine.weights import LogWeights

    P = len(history)
    path = folder / "checkpoint.npz"
    fingerprint = {"prior": prior.name}
    save_checkpoint(path, FilterState(history, state, LogWeights(np.zeros(P)), history[0], available, 2),
                    Recording(()), rng.bit_generator.state, fingerprint)
    resumed_rng = np.random.default_rng(0)
    restored, _ = load_checkpoint(path, fingerprint, Recording(()), resumed_rng)
    return restored, resumed_rng


def part_entries(state: PriorState, part: Part, n_particles: int) -> dict[str, np.ndarray]:
    """The entries ``part`` declares (:attr:`~priors.parts.Part.KEYS`) in a prior's ``state``, each checked to
    have one row per particle."""
    name = type(part).__name__
    assert isinstance(state, dict), f"a prior with the part {name} keeps no state dict"
    missing = [k for k in part.KEYS if k not in state]
    assert not missing, f"the prior's state lacks {name}'s entries {missing}"
    entries = {k: np.asarray(state[k]) for k in part.KEYS}
    for key, array in entries.items():
        assert array.shape[:1] == (n_particles,), f"{name}'s {key} has shape {array.shape} for {n_particles} particles"
    return entries


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
        apart (:class:`~tracker.engine.multiple_models.ComponentPrior`)."""
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

    def parts(self, prior: MotionPrior) -> Sequence[Part]:
        """The per-particle parts of the prior (:class:`priors.parts.Part`: ground diffusion, pace, root height,
        posture, ...) to check one by one through the part protocol, each in use by the prior. None by default."""
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
        prior, poses = self._prior_and_poses()
        P = self.particles
        history, available, state = rollout(prior, poses, P, 7, 2)
        rng = np.random.default_rng(13)
        restored, resumed_rng = checkpointed(prior, history, available, state, rng, tmp_path)
        direct = prior.sample(history, available, state, rng)[0]
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

    # --- each part, through the part protocol -----------------------------------------------------------

    def _parts(self, prior: MotionPrior) -> Sequence[Part]:
        parts = list(self.parts(prior))
        if not parts:
            import pytest

            pytest.skip(f"{prior.name}: no parts to check")
        for part in parts:
            assert isinstance(part, Part), f"{type(part).__name__} does not implement the part protocol (Part)"
        return parts

    def test_each_part_states_its_settings_under_its_options_names_among_the_priors(self):
        prior, _ = self._prior_and_poses()
        settings = prior.settings()
        for part in self._parts(prior):
            name, own = type(part).__name__, part.settings()
            json.dumps(own)
            assert list(own) == [o.name for o in part.OPTIONS], f"{name}'s settings are not its options: {list(own)}"
            for option in part.OPTIONS:
                assert option.parse(own[option.name], name) == own[option.name], \
                    f"{name}'s {option.name} is not a value its option takes"
                assert settings.get(option.name) == own[option.name], \
                    f"the prior's settings lack {name}'s {option.name}"

    def test_each_part_starts_its_declared_state_with_one_row_per_particle(self):
        prior, poses = self._prior_and_poses()
        P, known = self.particles, poses[:prior.order]
        started = prior.start(known, P, np.random.default_rng(21))
        for part in self._parts(prior):
            own = part.start(known, P, np.random.default_rng(21))
            assert sorted(own) == sorted(part.KEYS), \
                f"{type(part).__name__} started {sorted(own)}, declares {sorted(part.KEYS)}"
            part_entries(own, part, P)
            part_entries(started, part, P)

    def test_each_parts_state_is_reindexed_and_checkpointed_row_by_row(self, tmp_path):
        """After steps (the entries each part moves), resampling picks the rows of every entry a part declares,
        and a checkpoint file gives them back unchanged."""
        prior, poses = self._prior_and_poses()
        P = self.particles
        history, available, state = rollout(prior, poses, P, 22, 2)
        idx = np.random.default_rng(23).integers(0, P, P)
        picked = prior.reindex(state, idx)
        restored = checkpointed(prior, history, available, state, np.random.default_rng(24), tmp_path)[0].prior_state
        for part in self._parts(prior):
            entries = part_entries(state, part, P)
            for key, array in part_entries(picked, part, P).items():
                assert np.array_equal(array, entries[key][idx], equal_nan=True), \
                    f"{type(part).__name__}'s {key} after reindexing is not the picked rows"
            for key, array in part_entries(restored, part, P).items():
                assert np.array_equal(array, entries[key], equal_nan=True), \
                    f"{type(part).__name__}'s {key} came back from the checkpoint changed"

    def test_each_parts_summary_is_a_finite_number_the_prior_reports(self):
        """A part's summary is a finite number; a prior whose summary is its parts' quantities (``summary_kind``
        ``"quantity"``) reports it under the part's name (one that reports a posterior over its components or
        labels reports that instead)."""
        prior, poses = self._prior_and_poses()
        P = self.particles
        state = rollout(prior, poses, P, 25, 2)[2]
        weights = np.random.default_rng(26).dirichlet(np.ones(P))
        names = tuple(getattr(prior, "summary_names", ()) or ())
        for part in self._parts(prior):
            if not part.SUMMARY:
                continue
            value = part.summarize(state, weights)
            assert isinstance(value, float) and np.isfinite(value), f"{type(part).__name__}'s summary is {value!r}"
            if getattr(prior, "summary_kind", None) == "quantity":
                assert part.SUMMARY in names, f"the prior's summary lacks {type(part).__name__}'s {part.SUMMARY!r}"

    def test_each_part_draws_its_noise_from_the_generator_only(self):
        """The same seed gives the same numbers whatever numpy's global generator holds (which stays as it was),
        one row per particle; a part with nothing to draw leaves the generator where it was."""
        prior, poses = self._prior_and_poses()
        P, known = self.particles, poses[:prior.order]
        for part in self._parts(prior):
            name = type(part).__name__
            drawn = []
            for global_seed in (1, 2):
                np.random.seed(global_seed)
                before = np.random.get_state()[1].copy()
                rng = np.random.default_rng(27)
                start = part.start(known, P, rng)
                noise = part.noise(P, rng)
                after = rng.bit_generator.state
                assert np.array_equal(np.random.get_state()[1], before), f"{name} drew from numpy's global generator"
                drawn.append((start, noise, after))
            (start_a, a, after_a), (start_b, b, after_b) = drawn
            assert after_a == after_b, f"{name} drew other amounts of numbers from the same seed"
            for key in part.KEYS:
                assert np.array_equal(start_a[key], start_b[key], equal_nan=True), f"{name} started {key} otherwise"
            if a is None:
                assert b is None
                untouched = np.random.default_rng(27)
                part.start(known, P, untouched)
                state = untouched.bit_generator.state
                assert part.noise(P, untouched) is None and untouched.bit_generator.state == state, \
                    f"{name} drew numbers it does not use"
            else:
                assert np.array_equal(a, b), f"{name} drew other numbers from the same seed"
                assert np.shape(a)[:1] == (P,), f"{name}'s noise has shape {np.shape(a)} for {P} particles"
