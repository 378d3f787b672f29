"""Mixture tracking (tracker.engine.multiple_models): weights within and across components, resampling that keeps
every component's particles, switching between them, and the filter tracking a change of mode with it."""
import numpy as np
import pytest

from tracker.core.errors import InputError
from tracker.engine.filter import FilterConfig, ParticleFilter
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.multiple_models import Mixing, Mixture, mixture_weights, resample_components, switching
from tracker.engine.prior import MotionPrior
from tracker.engine.resampling import SCHEMES
from tracker.engine.weights import LogWeights


class ModePrior(MotionPrior):
    """A 1-D walker whose mode (the component) is its velocity: +1 or -1 per frame, plus noise 0.3."""

    order = 1
    name = "mode"
    summary_names = ("forward", "back")

    def __init__(self, switch=0.05, temperature=1.0):
        self.switch, self.temperature = switch, temperature

    def start(self, known, n_particles, rng):
        return {"mode": np.arange(n_particles) % 2}

    def sample(self, history, available, state, rng):
        v = np.where(state["mode"] == 0, 1.0, -1.0)[:, None]
        return history[:, -1] + v + 0.3 * rng.standard_normal((len(history), 1)), state

    def mixing(self):
        return Mixing(("forward", "back"), switching(2, self.switch), self.temperature)

    def component_of(self, state):
        return state["mode"]

    def relabel(self, state, component):
        return {"mode": np.array(component)}

    def summarize(self, state, weights):
        return np.bincount(state["mode"], weights=weights, minlength=2)

    def diffusion_std(self):
        return np.array([0.3])


class ExactModePrior(ModePrior):
    """The mode prior without noise: mode 0 steps to +1, mode 1 to -1."""

    def sample(self, history, available, state, rng):
        return history[:, -1] + np.where(state["mode"] == 0, 1.0, -1.0)[:, None], state


class Around(Likelihood):
    """Frame k: Gaussian log-likelihood (std 0.5) around ``truth[k]``."""

    def __init__(self, truth):
        self.truth = truth

    def prepare(self, frame: Frame) -> FrameLikelihood:
        centre = self.truth[frame.index]

        class Score(FrameLikelihood):
            def __call__(self, poses):
                return -0.5 * ((poses[:, 0] - centre) / 0.5) ** 2
        return Score()


def test_at_temperature_one_the_mixture_weights_are_the_plain_weights():
    rng = np.random.default_rng(0)
    carried, ll = LogWeights(rng.normal(size=12)), rng.normal(size=12) * 5
    mix = Mixture(np.arange(12) % 3, switching(3, 0.1))
    assert np.allclose(mixture_weights(carried, ll, mix), carried.add(ll).normalised)


def test_temperature_flattens_the_components_weights_not_the_weights_within():
    ll = np.array([0.0, -40.0, -20.0, -20.0])  # component 0 holds the single best particle
    mix = Mixture(np.array([0, 0, 1, 1]), switching(2, 0.0), temperature=20.0)
    w = mixture_weights(LogWeights.uniform(4), ll, mix)
    plain = mixture_weights(LogWeights.uniform(4), ll, Mixture(mix.component, mix.transition))
    assert plain[0] > 0.999999  # untempered, one lucky particle decides
    pi0 = w[:2].sum()
    assert 0.5 < pi0 < 0.9 and np.isclose(w.sum(), 1.0)  # exp(0/20)+exp(-2) against 2 exp(-1)
    assert np.isclose(w[1] / w[0], np.exp(-40.0)) and np.isclose(w[2], w[3])  # within: the full likelihood


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_resampling_draws_any_number_with_the_expected_counts(scheme):
    w = np.array([0.1, 0.6, 0.3])
    counts = np.mean([np.bincount(SCHEMES[scheme](w, np.random.default_rng(i), 50), minlength=3)
                      for i in range(200)], axis=0)
    assert np.allclose(counts, 50 * w, atol=1.0)


def test_each_component_is_redrawn_from_all_particles_through_the_transition():
    component = np.array([0, 0, 0, 1, 1])
    mix = Mixture(component, switching(2, 0.1))
    weights = np.array([0.5, 0.3, 0.2, 0.0, 0.0])  # component 1 has lost all its weight
    idx, carried = resample_components(weights, mix, np.random.default_rng(0), SCHEMES["systematic"])
    assert np.all(np.isin(idx[:3], [0, 1, 2])) and np.all(np.isin(idx[3:], [0, 1, 2]))  # restarts from component 0
    totals = np.exp(carried.log_w)
    assert np.isclose(totals[:3].sum(), 0.9) and np.isclose(totals[3:].sum(), 0.1)  # the predicted weights


def test_the_mixture_is_checked():
    with pytest.raises(InputError, match="every component needs"):
        Mixture(np.zeros(4, int), switching(2, 0.1)).check(4)
    with pytest.raises(InputError, match="rows must be probabilities"):
        Mixture(np.arange(4) % 2, np.array([[0.5, 0.4], [0.0, 1.0]])).check(4)
    with pytest.raises(InputError, match="one component in 0..C-1 per particle"):
        Mixture(np.arange(3) % 2, switching(2, 0.1)).check(4)


def test_the_filter_follows_a_change_of_mode_and_keeps_both_components():
    truth = np.concatenate([np.arange(1, 21), 20 - np.arange(1, 21)]).astype(float)  # forward 20, back 20
    pf = ParticleFilter(ModePrior(switch=0.05), Around(truth), FilterConfig(n_particles=200),
                        np.random.default_rng(3))
    state = pf.start(np.zeros((1, 1)))
    posterior, estimates = [], []
    for k in range(len(truth)):
        state, step = pf.step(state, Frame(k, ()))
        assert np.array_equal(np.bincount(state.prior_state["mode"]), [100, 100])  # the shares never change
        posterior.append(step.prior_summary[0])
        estimates.append(step.mean[0])
    posterior = np.array(posterior)
    assert np.all(posterior[3:20] > 0.9) and np.all(posterior[24:] < 0.1)  # forward, then back within 4 frames
    assert np.max(np.abs(np.array(estimates) - truth)) < 1.5
    again = ParticleFilter(ModePrior(switch=0.05), Around(truth), FilterConfig(n_particles=200),
                           np.random.default_rng(3)).run(np.zeros((1, 1)), [Frame(k, ()) for k in range(len(truth))])
    assert np.allclose(again["mean_poses"][:, 0], estimates)  # run() and step() agree, deterministic per seed


def test_annealed_components_keep_their_particles_and_still_follow_the_change():
    truth = np.concatenate([np.arange(1, 21), 20 - np.arange(1, 21)]).astype(float)
    pf = ParticleFilter(ModePrior(switch=0.05), Around(truth), FilterConfig(n_particles=200, annealing_layers=3),
                        np.random.default_rng(3))
    state = pf.start(np.zeros((1, 1)))
    posterior, errors = [], []
    for k in range(len(truth)):
        state, step = pf.step(state, Frame(k, ()))
        assert np.array_equal(state.prior_state["mode"], np.arange(200) % 2)  # each position keeps its component
        posterior.append(step.prior_summary[0])
        errors.append(abs(step.mean[0] - truth[k]))
    posterior = np.array(posterior)
    assert np.all(posterior[3:20] > 0.9) and np.all(posterior[24:] < 0.1)
    assert max(errors) < 1.5


def test_annealing_redraws_each_component_from_its_own_particles():
    pf = ParticleFilter(ModePrior(), Around([0.0]), FilterConfig(n_particles=100, annealing_layers=4),
                        np.random.default_rng(1))
    state = pf.start(np.zeros((1, 1)))
    mode = state.prior_state["mode"]
    x = np.where(mode == 0, 0.0, 10.0)[:, None] + np.random.default_rng(2).random((100, 1))  # 1 far from the truth
    frame_lik = pf.likelihood.prepare(Frame(0, ()))
    out, _, st, weights = pf._anneal(x, state.history, state.prior_state, frame_lik(x), frame_lik)
    assert np.all(np.abs(out[mode == 1, 0] - 10.5) < 3) and np.all(np.abs(out[mode == 0, 0]) < 3)
    assert np.array_equal(st["mode"], mode) and np.all(np.isfinite(weights.log_w))


def test_annealed_components_are_weighed_on_the_priors_own_samples(monkeypatch):
    import tracker.engine.multiple_models as engine

    seen = []

    def spy(carried, ll, mix, evidence=None):
        seen.append(evidence)
        return mixture_weights(carried, ll, mix, evidence)

    monkeypatch.setattr(engine, "mixture_weights", spy)
    pf = ParticleFilter(ExactModePrior(), Around([0.5]), FilterConfig(n_particles=10, annealing_layers=3),
                        np.random.default_rng(0))
    pf.step(pf.start(np.zeros((1, 1))), Frame(0, ()))
    expected = -0.5 * ((np.where(np.arange(10) % 2 == 0, 1.0, -1.0) - 0.5) / 0.5) ** 2
    assert seen[0] is not None and np.allclose(seen[0], expected)


def test_an_annealed_frame_that_only_a_lost_component_explains_is_a_recovery():
    from dataclasses import replace

    class Left(Around):  # only poses below 0 explain the frame
        def prepare(self, frame):
            class Score(FrameLikelihood):
                def __call__(self, poses):
                    return np.where(poses[:, 0] < 0, -0.5 * ((poses[:, 0] + 1) / 0.5) ** 2, -np.inf)
            return Score()

    pf = ParticleFilter(ExactModePrior(switch=0.0), Left([0.0]), FilterConfig(n_particles=20, annealing_layers=3),
                        np.random.default_rng(0))
    state = pf.start(np.zeros((1, 1)))
    lost = np.where(np.arange(20) % 2 == 1, -np.inf, np.log(0.1))  # mode 1 (stepping left) carries no weight
    _, step = pf.step(replace(state, weights=LogWeights(lost)), Frame(0, ()))
    assert step.recovered and np.all(np.isfinite(step.mean))


def test_an_annealed_frame_whose_weighted_particles_have_no_evidence_is_a_recovery():
    """The annealing layers find the frame (from particles that carry no weight) while no particle that carries
    weight had any evidence before them: no component has a weight, and the filter recovers at once rather than
    carrying no weight into the next frame."""
    from dataclasses import replace

    class Split(ExactModePrior):  # mode 0: particles 0, 4, 8, ... step to 1.5, particles 2, 6, ... to 0.5
        def sample(self, history, available, state, rng):
            x, state = super().sample(history, available, state, rng)
            return x + np.where(np.arange(len(x)) % 4 == 0, 0.5, -0.5)[:, None], state

    class Beyond(Around):  # only poses beyond 1 explain the frame
        def prepare(self, frame):
            class Score(FrameLikelihood):
                def __call__(self, poses):
                    return np.where(poses[:, 0] > 1, -0.5 * ((poses[:, 0] - 1.5) / 0.5) ** 2, -np.inf)
            return Score()

    pf = ParticleFilter(Split(switch=0.0), Beyond([0.0]), FilterConfig(n_particles=20, annealing_layers=3),
                        np.random.default_rng(0))
    state = pf.start(np.zeros((1, 1)))
    carried = LogWeights(np.where(np.arange(20) % 4 == 2, np.log(0.2), -np.inf))  # only the steps to 0.5
    new, step = pf.step(replace(state, weights=carried), Frame(0, ()))
    assert step.recovered and np.isfinite(step.ess) and new.weights.any_finite


def test_the_components_are_weighed_on_the_evidence_and_particles_within_on_the_likelihood():
    mix = Mixture(np.array([0, 0, 1, 1]), switching(2, 0.0))
    carried = LogWeights(np.log(np.full(4, 0.25)))
    ll = np.log(np.array([0.1, 0.3, 0.8, 0.8]))  # annealed: component 1 fits better now
    evidence = np.log(np.array([0.5, 0.5, 0.1, 0.1]))  # the prior's own samples: component 0 predicted better
    W = mixture_weights(carried, ll, mix, evidence)
    assert np.allclose(W, [0.25 * 5 / 6, 0.75 * 5 / 6, 0.5 / 6, 0.5 / 6])
    assert np.allclose(mixture_weights(carried, ll, mix), mixture_weights(carried, ll, mix, ll))


def test_the_transition_is_read_from_row_to_column():
    component = np.array([0, 0, 1, 1])
    T = np.array([[1.0, 0.0], [0.5, 0.5]])  # 0 never leaves; 1 moves to 0 half the time
    weights = np.array([0.0, 0.0, 0.5, 0.5])
    idx, carried = resample_components(weights, Mixture(component, T), np.random.default_rng(0), SCHEMES["systematic"])
    totals = np.exp(carried.log_w)
    assert np.isclose(totals[:2].sum(), 0.5) and np.isclose(totals[2:].sum(), 0.5)
    assert np.all(np.isin(idx, [2, 3]))  # component 0 restarts from component 1's particles


def test_components_start_equal_whatever_their_sizes():
    mix = Mixture(np.arange(10) % 3, switching(3, 0.1))  # 4, 3 and 3 particles
    w = mix.start_weights().normalised
    assert np.allclose(np.bincount(mix.component, weights=w), 1 / 3)


def test_broken_likelihoods_and_lost_frames_keep_the_components():
    truth = np.arange(1, 13, dtype=float)
    nan_at, lost_at = 4, 8

    class Broken(Around):
        def prepare(self, frame):
            inner = super().prepare(frame)

            class Score(FrameLikelihood):
                def __call__(self, poses):
                    ll = inner(poses)
                    if frame.index == nan_at:
                        ll[::2] = np.nan  # half the particles, in both components
                    if frame.index == lost_at:
                        ll[:] = -np.inf  # nothing explains the frame
                    return ll
            return Score()

    pf = ParticleFilter(ModePrior(), Broken(truth), FilterConfig(n_particles=40), np.random.default_rng(1))
    state = pf.start(np.zeros((1, 1)))
    for k in range(len(truth)):
        state, step = pf.step(state, Frame(k, ()))
        assert np.all(np.isfinite(step.mean)) and np.isclose(step.prior_summary.sum(), 1.0)
        assert np.array_equal(np.bincount(state.prior_state["mode"], minlength=2), [20, 20])
        assert step.recovered == (k == lost_at)
    assert abs(step.mean[0] - truth[-1]) < 2.0


def test_a_tempered_mixture_still_follows_the_change_of_mode():
    truth = np.concatenate([np.arange(1, 21), 20 - np.arange(1, 21)]).astype(float)
    out = ParticleFilter(ModePrior(switch=0.05, temperature=4.0), Around(truth), FilterConfig(n_particles=200),
                         np.random.default_rng(5)).run(np.zeros((1, 1)), [Frame(k, ()) for k in range(len(truth))],
                                                       record=("mean_poses", "prior_summary"))
    forward = out["prior_summary"][:, 0]
    assert np.all(forward[5:20] > 0.8) and np.all(forward[26:] < 0.2)
    assert np.max(np.abs(out["mean_poses"][:, 0] - truth)) < 2.0


class Walker(MotionPrior):
    """A 1-D random walk with unit steps of noise 0.5, no components."""

    order = 1
    name = "walker"

    def sample(self, history, available, state, rng):
        return history[:, -1] + 1.0 + 0.5 * rng.standard_normal((len(history), 1)), state

    def diffusion_std(self):
        return np.array([0.5])


class OneComponent(Walker):
    """The walker as a mixture of one component: every particle in component 0, nothing to switch to."""

    def start(self, known, n_particles, rng):
        return {"component": np.zeros(n_particles, np.int64)}

    def mixing(self):
        return Mixing(("only",), np.ones((1, 1)))

    def component_of(self, state):
        return state["component"]

    def relabel(self, state, component):
        return {"component": np.array(component)}


@pytest.mark.parametrize("layers", [1, 3])
def test_a_mixture_of_one_component_tracks_as_the_plain_prior(layers):
    """Mixture tracking is a strategy of the filter, not a branch in it: with one component it weighs and draws as
    plain SIR does when that resamples every frame (the same particles every frame), recovery included."""
    truth = np.arange(1, 16, dtype=float)

    class Lost(Around):  # frame 6 is explained only well behind the particles: only the recovery's draws fit
        def prepare(self, frame):
            inner = super().prepare(frame)

            class Score(FrameLikelihood):
                def __call__(self, poses):
                    ll = inner(poses)
                    return np.where(poses[:, 0] < truth[5] - 0.8, ll, -np.inf) if frame.index == 6 else ll
            return Score()

    config = FilterConfig(n_particles=50, ess_threshold=1.0, annealing_layers=layers)
    runs = [ParticleFilter(prior, Lost(truth), config, np.random.default_rng(4)).run(
        np.zeros((1, 1)), [Frame(k, ()) for k in range(len(truth))],
        record=("particles", "mean_poses", "resampled", "recovered")) for prior in (Walker(), OneComponent())]
    assert runs[0]["recovered"][6] and runs[1]["recovered"][6]
    # the same particles drawn every frame (a different draw moves a particle by about 0.5, not by rounding: the
    # weights, and so the estimate a recovery restarts from, agree to rounding, not to the bit)
    assert np.allclose(runs[0]["particles"], runs[1]["particles"], rtol=0, atol=1e-12)
    assert np.array_equal(runs[0]["resampled"], runs[1]["resampled"]) and runs[0]["resampled"].all()
    assert np.allclose(runs[0]["mean_poses"], runs[1]["mean_poses"], rtol=0, atol=1e-12)


def test_the_filter_chooses_its_weighing_once_and_knows_nothing_of_components():
    """The filter's code names no part of the component API: the strategy object is chosen from the prior
    (tracker.engine.weighing) and the filter only calls it."""
    import ast
    import inspect

    import tracker.engine.filter as engine
    from tracker.engine.multiple_models import MixtureTracking
    from tracker.engine.weighing import PlainSIR, Weighing

    tree = ast.parse(inspect.getsource(engine))
    used = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    used |= {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    used |= {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
    modules = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    component_api = {"Mixture", "Mixing", "MixtureTracking", "ComponentPrior", "mixing", "mixing_of", "mixture",
                     "component_of", "relabel", "mixture_weights", "resample_components"}
    assert not used & component_api and "tracker.engine.multiple_models" not in modules
    rng = np.random.default_rng(0)
    plain = ParticleFilter(Walker(), Around([0.0]), FilterConfig(n_particles=4), rng).weighing
    mixed = ParticleFilter(ModePrior(), Around([0.0]), FilterConfig(n_particles=4), rng).weighing
    assert isinstance(plain, PlainSIR) and isinstance(mixed, MixtureTracking)
    assert isinstance(plain, Weighing) and isinstance(mixed, Weighing)


def test_the_motion_prior_core_is_small_and_the_rest_optional():
    from tracker.engine.prior import label_for, restart, summarize, summary_of

    core = {n for n in vars(MotionPrior) if not n.startswith("_")}
    assert core == {"order", "name", "start", "sample", "reindex", "diffusion_std", "settings"}
    walker = Walker()
    assert summary_of(walker) == ((), "posterior") and summarize(walker, None, np.ones(3) / 3) is None
    assert label_for(walker, 1) == "walker"
    assert restart(walker, None, np.zeros((1, 1)), 3, np.random.default_rng(0)) is None  # start from the estimates
    assert summary_of(ModePrior()) == (("forward", "back"), "posterior")  # the kind defaults to a posterior
