"""An ensemble of priors of one order (several CRBM model files of one order): each particle keeps one member,
which draws its poses and keeps its state; resampling moves particles toward the members the images support."""
import numpy as np
import pytest

from priors.ensemble import EnsemblePrior
from tracker.core.errors import InputError
from tracker.engine.filter import FilterConfig, ParticleFilter
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.prior import MotionPrior


class Step(MotionPrior):
    """Moves every particle by ``step`` (no noise); its state counts the samples each particle drew from it and
    its summary is the weighted mean count."""

    name = "step"
    summary_names, summary_kind = ("count",), "quantity"

    def __init__(self, step, order=1):
        self.step, self.order = np.asarray(step, float), order

    def start(self, known, n, rng):
        return {"count": np.zeros(n)}

    def sample(self, history, available, state, rng):
        return history[:, -1] + self.step, {"count": state["count"] + 1}

    def diffusion_std(self):
        return np.abs(self.step)

    def summarize(self, state, weights):
        return np.array([np.sum(weights * state["count"])])


def test_each_particle_keeps_its_member_and_only_its_members_state_moves():
    prior = EnsemblePrior([Step([1.0, 0.0]), Step([0.0, 1.0])])
    rng = np.random.default_rng(0)
    state = prior.start(np.zeros((1, 2)), 5, rng)
    assert state["component"].tolist() == [0, 1, 0, 1, 0]
    history = np.zeros((5, 1, 2))
    poses, state = prior.sample(history, 1, state, rng)
    assert np.array_equal(poses[state["component"] == 0], [[1, 0]] * 3)
    assert np.array_equal(poses[state["component"] == 1], [[0, 1]] * 2)
    assert state["model_0"]["count"].tolist() == [1, 0, 1, 0, 1]  # the rows of member 0's particles only
    assert state["model_1"]["count"].tolist() == [0, 1, 0, 1, 0]
    state = prior.reindex(state, np.array([1, 1, 1, 3, 3]))  # resampling keeps member 1's particles only
    poses, state = prior.sample(poses[[1, 1, 1, 3, 3], None], 1, state, rng)
    assert np.array_equal(poses, [[0, 2]] * 5) and state["model_1"]["count"].tolist() == [2] * 5
    # The summary: each member's particles under the whole set's weights, summed (the weighted mean count).
    weights = np.array([0.1, 0.2, 0.3, 0.2, 0.2])
    assert prior.summarize(state, weights)[0] == pytest.approx(2.0)
    assert prior.label_for(1) == "step (ensemble of 2)" and prior.settings()["ensemble_of"] == 2


def test_the_filter_moves_particles_to_the_member_the_images_support():
    """The person moves by +1 per frame in x; member 1 predicts that, member 0 predicts standing still."""

    class Truth(Likelihood):
        def prepare(self, frame):
            class Score(FrameLikelihood):
                def __call__(self, poses):
                    return -0.5 * np.sum((poses - [frame.index + 1.0, 0.0]) ** 2, axis=1) / 0.3 ** 2
            return Score()

    prior = EnsemblePrior([Step([0.0, 0.0]), Step([1.0, 0.0])])
    seen = []
    pf = ParticleFilter(prior, Truth(), FilterConfig(n_particles=200), np.random.default_rng(1))
    pf.run(np.zeros((1, 2)), [Frame(k, ()) for k in range(6)], on_state=lambda st, rec: seen.append(st))
    assert np.mean(seen[-1].prior_state["component"] == 1) > 0.95


def test_an_ensemble_of_mixed_priors_is_refused():
    with pytest.raises(InputError, match="at least two"):
        EnsemblePrior([Step([1.0, 0.0])])
    with pytest.raises(InputError, match="one kind and order"):
        EnsemblePrior([Step([1.0, 0.0]), Step([1.0, 0.0], order=2)])


@pytest.mark.slow
def test_crbm_files_of_one_order_track_as_an_ensemble(mocap_dir, walk_32_frames, tmp_path):
    import tracker

    clips = [mocap_dir / "07" / "07_01.amc"]
    for seed in (0, 1):
        tracker.train("crbm", clips, order=2, epochs=3, hidden=10, seed=seed).save(tmp_path / f"m{seed}.pt")
    tracker.train("crbm", clips, order=1, epochs=3, hidden=10, grow_from="none", seed=0).save(tmp_path / "o1.pt")
    run = tracker.track(walk_32_frames, "crbm", models=[tmp_path / "m0.pt", tmp_path / "m1.pt"], particles=60,
                        frames=6, seed=0)
    assert run.records["prior_labels"][-1] == "crbm order 2 (ensemble of 2)"
    with pytest.raises(InputError, match="one model per order"):
        tracker.track(walk_32_frames, "crbm", models=[tmp_path / "o1.pt", tmp_path / "m0.pt", tmp_path / "m1.pt"],
                      particles=60, frames=6, seed=0)
