"""The mixture of motion models (priors.mixture): weighed by evidence, switching, and built from the registry.

The filter cases are synthetic and need no images: the "images" are a Gaussian likelihood around a known
trajectory in a 3-number pose space, and the components are drifts of known velocity, so which component
explains each frame is known.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from priors.mixture import MixturePrior, numbered
from tracker.core.errors import InputError
from tracker.engine.filter import FilterConfig, ParticleFilter
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.prior import MotionPrior

D = 3


class Drift(MotionPrior):
    """``x_t = x_{t-1} + velocity + N(0, std^2)``: a motion model that explains a person moving at ``velocity``."""

    order = 1

    def __init__(self, velocity: float, std: float = 2.0, name: str = "drift"):
        self.velocity, self.std, self.name = np.array([velocity, 0.0, 0.0]), std, name

    def sample(self, history, available, state, rng):
        return history[:, -1] + self.velocity + self.std * rng.standard_normal(history[:, -1].shape), state

    def diffusion_std(self):
        return np.full(D, self.std)


class Around(Likelihood):
    """Log-likelihood ``-|x - truth_t|^2 / (2 sigma^2)`` around the trajectory ``truth`` ``T x D``."""

    def __init__(self, truth: np.ndarray, sigma: float = 3.0):
        self.truth, self.sigma = truth, sigma

    def prepare(self, frame: Frame) -> FrameLikelihood:
        target, sigma = self.truth[frame.index], self.sigma

        class _Bound(FrameLikelihood):
            def __call__(self, poses):
                return -np.sum((poses - target) ** 2, axis=1) / (2 * sigma ** 2)
        return _Bound()


def track(truth: np.ndarray, prior: MotionPrior, seed: int = 0, particles: int = 400, layers: int = 1):
    """The posterior over the prior's components per tracked frame ``(T - 1) x C`` and the estimates."""
    pf = ParticleFilter(prior, Around(truth), FilterConfig(particles, annealing_layers=layers),
                        np.random.default_rng(seed))
    frames = [Frame(t, (np.zeros((2, 2), np.uint8),)) for t in range(1, len(truth))]
    out = pf.run(truth[:1], frames, record=("mean_poses", "prior_summary"))
    return np.asarray(out["prior_summary"]), np.asarray(out["mean_poses"])


def trajectory(velocities: list[tuple[int, float]]) -> np.ndarray:
    """Poses ``T x D`` moving along the first number at ``velocity`` for ``frames`` frames, per segment."""
    steps = np.concatenate([np.full(n, v) for n, v in velocities])
    x = np.zeros((len(steps) + 1, D))
    x[1:, 0] = np.cumsum(steps)
    return x


def test_a_component_that_cannot_explain_the_frames_loses_its_weight_within_a_few_frames():
    truth = trajectory([(20, 10.0)])  # moving at 10 per frame: the standing component falls behind at once
    for layers in (1, 3):
        posterior, mean = track(truth, MixturePrior([Drift(0.0, name="standing"), Drift(10.0, name="moving")]),
                                layers=layers)
        assert posterior.shape == (20, 2)
        assert np.allclose(posterior.sum(axis=1), 1.0)
        assert np.all(posterior[3:, 1] > 0.9), (layers, posterior[:, 1])
        assert np.abs(mean[3:, 0] - truth[4:, 0]).max() < 5.0  # the estimate follows the winner


def test_the_weight_switches_back_when_the_motion_returns():
    truth = trajectory([(15, 10.0), (15, 0.0), (15, 10.0)])  # walk, stand, walk again
    prior = MixturePrior([Drift(0.0, name="standing"), Drift(10.0, name="moving")])
    posterior, _ = track(truth, prior, seed=1)
    moving = posterior[:, 1]
    assert np.all(moving[4:15] > 0.9), moving[:15]
    assert np.all(moving[19:30] < 0.1), moving[15:30]
    assert np.all(moving[34:45] > 0.9), moving[30:]


def test_without_switching_a_component_that_lost_its_weight_stays_lost():
    truth = trajectory([(15, 10.0), (15, 0.0)])
    posterior, _ = track(truth, MixturePrior([Drift(0.0, name="standing"), Drift(10.0, name="moving")], switch=0.0),
                         seed=1)
    assert posterior[10, 1] > 0.99
    assert posterior[-1, 0] < 0.5  # the standing particles were left behind at the start and cannot catch up


def test_mixture_settings_are_checked_and_reported():
    with pytest.raises(InputError, match="at least two"):
        MixturePrior([Drift(0.0)])
    for switch in (1.0, 0.7, -0.1):  # the bounds the option declares, the same as on the command line
        with pytest.raises(InputError, match="mixture: switch must be at least 0 and at most 0.5"):
            MixturePrior([Drift(0.0), Drift(1.0)], switch=switch)
    with pytest.raises(InputError, match="mixture: evidence_temperature must be at least 1"):
        MixturePrior([Drift(0.0), Drift(1.0)], temperature=0.5)
    assert MixturePrior([Drift(0.0), Drift(1.0)], switch=0.5).switch == 0.5
    with pytest.raises(InputError, match="needs at least 2 particles"):
        MixturePrior([Drift(0.0), Drift(1.0)]).start(np.zeros((1, D)), 1, np.random.default_rng(0))
    prior = MixturePrior([Drift(0.0), Drift(1.0)])
    assert prior.summary_names == ("drift", "drift 2")
    assert numbered(["crbm", "zero-velocity", "crbm"]) == ("crbm", "zero-velocity", "crbm 2")
    assert prior.settings()["components"] == ["drift", "drift 2"] == list(prior.labels)
    state = prior.start(np.zeros((1, D)), 5, np.random.default_rng(0))
    assert list(state["component"]) == [0, 0, 0, 1, 1]


@pytest.mark.slow
def test_a_particle_that_switches_component_is_drawn_from_its_own_history(mocap_dir, walk_07_01):
    """A CRBM component takes a particle from another component with the step out of that particle's own newest
    pose (MotionPrior.adopt), not the step its position held."""
    import tracker
    from tracker.core.representation import pending_step
    from tracker.app.api import build_prior

    model = tracker.train("crbm", [mocap_dir / "07" / "07_01.amc"], order=1, hidden=10, epochs=2, seed=0,
                          pace_input=False)

    class _Seq:
        model, fps, root = walk_07_01.model, 60.0, Path("mixture")

    prior = build_prior("mixture", _Seq(), [model], step_std=np.full(walk_07_01.poses.shape[1], 1.0))
    poses = walk_07_01.poses
    rng = np.random.default_rng(0)
    state = prior.start(poses[:2], 6, rng)
    history = np.repeat(poses[None, :2], 6, axis=0)
    history[3:] = poses[None, 10:12]  # the zero-velocity particles are elsewhere, moving differently
    idx = np.array([3, 4, 2, 3, 4, 5])  # positions 0 and 1 (CRBM) take zero-velocity particles 3 and 4
    moved = prior.reindex(state, idx)
    assert list(moved["arrived"]) == [True, True, False, False, False, False]
    adopted = prior.components[0].adopt(moved["model_0"], history[idx], 2, rng)
    assert np.allclose(adopted["step"][:2], pending_step(poses[10:12]))
    assert np.allclose(adopted["step"][2], pending_step(poses[:2]))
    _, after = prior.sample(history[idx], 2, moved, rng)
    assert not after["arrived"].any()


def test_the_mixture_is_built_from_the_registry_in_one_line(mocap_dir, walk_07_01):
    from tracker.app.api import build_prior

    class _Seq:
        model, fps, root = walk_07_01.model, 60.0, Path("mixture")

    std = np.full(walk_07_01.poses.shape[1], 1.0)
    prior = build_prior("mixture", _Seq(), [], step_std=std, components="zero-velocity,constant-velocity",
                        switch=0.1)
    assert prior.summary_names == ("zero-velocity", "constant-velocity") and prior.order == 2
    assert prior.settings()["switch"] == 0.1
    with pytest.raises(InputError, match=r"takes 1 model file \(crbm: 1\), got 0$"):
        build_prior("mixture", _Seq(), [], step_std=std, components="crbm:gibbs_steps=3,zero-velocity")
    with pytest.raises(InputError, match="components must name two or more"):
        build_prior("mixture", _Seq(), [], step_std=std, components="zero-velocity")
    with pytest.raises(InputError, match=r"crbm, zero-velocity takes 2 model files \(crbm: 2\), got 1$"):
        build_prior("mixture", _Seq(), [Path("a.pt")], step_std=std, components="crbm:models=2,zero-velocity")
    with pytest.raises(InputError, match=r"takes no model files, got 1$"):
        build_prior("mixture", _Seq(), [Path("a.pt")], step_std=std, components="zero-velocity,constant-velocity")
    with pytest.raises(InputError, match="unknown prior 'nonsense'"):
        build_prior("mixture", _Seq(), [], step_std=std, components="zero-velocity,nonsense")


class Styled(Drift):
    """A drift whose particles carry one of two labels kept apart by the filter (as an FCRBM's styles are)."""

    summary_names, summary_kind = ("slow", "fast"), "posterior"

    def start(self, known, n_particles, rng):
        return {"style": np.arange(n_particles) % 2}

    def sample(self, history, available, state, rng):
        speed = np.where(state["style"] == 1, 10.0, 0.0)[:, None] * np.array([1.0, 0.0, 0.0])
        return history[:, -1] + speed + self.std * rng.standard_normal(history[:, -1].shape), state

    def mixing(self):
        from tracker.engine.multiple_models import Mixing, switching
        return Mixing(("slow", "fast"), switching(2, 0.1), 10.0)

    def component_of(self, state):
        return state["style"]

    def relabel(self, state, component):
        return {**state, "style": np.array(component)}

    def summarize(self, state, weights):
        return np.bincount(state["style"], weights=weights, minlength=2)


def test_a_model_with_components_of_its_own_takes_part_with_each_of_them():
    prior = MixturePrior([Drift(0.0, name="still"), Styled(0.0, name="styled")], switch=0.2)
    assert prior.summary_names == ("still", "styled slow", "styled fast")
    state = prior.start(np.zeros((1, D)), 8, np.random.default_rng(0))
    mix = prior.mixing().at(prior.component_of(state)).check(8)
    assert list(mix.component) == [0, 0, 0, 0, 1, 2, 1, 2]
    assert np.allclose(mix.transition, [[0.8, 0.1, 0.1], [0.2, 0.72, 0.08], [0.2, 0.08, 0.72]])
    relabelled = prior.relabel(state, np.array([0, 0, 0, 0, 2, 2, 1, 1]))
    assert list(relabelled["model_1"]["style"][4:]) == [1, 1, 0, 0]
    truth = trajectory([(20, 10.0)])
    posterior, _ = track(truth, MixturePrior([Drift(0.0, name="still"), Styled(0.0, name="styled")]))
    assert np.all(posterior[4:, 2] > 0.85), posterior  # the fast label of the styled model explains the frames


@pytest.mark.slow
def test_a_gpdm_takes_an_arriving_particle_at_the_latent_point_of_its_own_poses(mocap_dir, walk_07_01):
    """What GPDMPrior.adopt gives each arriving particle is what starting from that particle's poses gives."""
    import tracker
    from tracker.app.api import build_prior

    model = tracker.train("gpdm", [mocap_dir / "07" / "07_01.amc"], iterations=3, seed=0)

    class _Seq:
        model, fps, root = walk_07_01.model, 60.0, Path("mixture")

    gpdm = build_prior("gpdm", _Seq(), [model])
    poses, rng = walk_07_01.poses, np.random.default_rng(0)
    history = np.stack([poses[0:3], poses[20:23], poses[40:43]])  # three particles, three poses each
    state = gpdm.start(poses[:2], 3, rng)
    adopted = gpdm.adopt(state, history, 3, rng)
    for i in range(3):
        alone = gpdm.start(history[i], 1, rng)
        assert np.allclose(adopted["latent"][i], alone["latent"][0], atol=1e-4), i
        assert np.allclose(adopted["step"][i], alone["step"][0])
    assert np.array_equal(adopted["height_offset"], state["height_offset"])  # a slow quantity stays


class Counting(Drift):
    """A drift counting its frames per particle, whose restart carries the count on (as an FCRBM's clock is)."""

    def start(self, known, n_particles, rng):
        return {"count": np.zeros(n_particles, np.int64)}

    def sample(self, history, available, state, rng):
        return super().sample(history, available, state, rng)[0], {"count": state["count"] + 1}

    def restart(self, state, recent, n_particles, rng):
        return {"count": np.full(n_particles, state["count"][0] + 100)}


def test_a_restart_after_a_lost_frame_reads_each_component_from_its_own_particles():
    prior = MixturePrior([Drift(0.0, name="still"), Counting(0.0, name="counting")])
    rng = np.random.default_rng(0)
    state = prior.start(np.zeros((1, D)), 6, rng)
    history = np.zeros((6, 1, D))
    for _ in range(2):
        _, state = prior.sample(history, 1, state, rng)
    assert list(state["model_1"]["count"]) == [0, 0, 0, 2, 2, 2]  # rows of the other block are never updated
    restarted = prior.restart(state, np.zeros((1, D)), 6, rng)
    assert np.all(restarted["model_1"]["count"] == 102)


@pytest.mark.slow
def test_two_models_of_one_prior_given_as_objects_are_numbered(mocap_dir, walk_07_01):
    import tracker
    from tracker.app.api import build_prior

    model = tracker.train("crbm", [mocap_dir / "07" / "07_01.amc"], order=1, hidden=10, epochs=1, seed=0,
                          pace_input=False)

    class _Seq:
        model, fps, root = walk_07_01.model, 60.0, Path("mixture")

    prior = build_prior("mixture", _Seq(), [model, model], components="crbm,crbm")
    assert prior.summary_names == ("crbm", "crbm 2")


@pytest.mark.slow
def test_an_ensemble_component_adopts_arriving_particles_member_by_member(mocap_dir, walk_07_01):
    import tracker
    from priors.ensemble import EnsemblePrior
    from tracker.app.api import build_prior
    from tracker.core.representation import pending_step

    model = tracker.train("crbm", [mocap_dir / "07" / "07_01.amc"], order=1, hidden=10, epochs=1, seed=0,
                          pace_input=False)

    class _Seq:
        model, fps, root = walk_07_01.model, 60.0, Path("mixture")

    ensemble = EnsemblePrior([build_prior("crbm", _Seq(), [model]) for _ in range(2)])
    poses, rng = walk_07_01.poses, np.random.default_rng(0)
    state = ensemble.start(poses[:2], 4, rng)
    history = np.stack([poses[2 * i:2 * i + 2] for i in range(4)]) + 0.0
    adopted = ensemble.adopt(state, history, 2, rng)
    for i in range(4):
        member = adopted[f"model_{i % 2}"]
        assert np.allclose(member["step"][i], pending_step(history[i])), i
