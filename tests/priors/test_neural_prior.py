"""The neural prior: its mixture density network samples its own density, draws the same row by row as in a
batch, reads any history length as training taught it, and its model files and training checkpoints round-trip
(the prior contract is run for it in test_prior_contract.py)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import torch

from priors.neural.file import load_neural
from priors.neural.model import MDN, NeuralModel
from tracker.core.errors import InputError


def toy_mdn(means: list[list[float]], scales: list[list[float]], weights: list[float]) -> MDN:
    """An MDN of order 1 whose mixture is the same for every history: components of ``means`` and ``scales``
    (M x K, added to the last frame) with ``weights`` (M,)."""
    M, K = len(means), len(means[0])
    torch.manual_seed(0)
    net = MDN(K, order=1, hidden=4, layers=1, components=M)
    with torch.no_grad():
        for head in (net.logits, net.means, net.log_scales):
            head.weight.zero_()
        net.logits.bias.copy_(torch.log(torch.tensor(weights)))
        net.means.bias.copy_(torch.tensor(means).reshape(-1))
        net.log_scales.bias.copy_(torch.log(torch.tensor(scales)).reshape(-1))
    return net


def test_samples_follow_the_density_the_network_states():
    """A 1-D mixture of two Gaussians (weights 0.3 and 0.7 at -2 and 1.5, scales 0.5 and 1): the histogram of
    200,000 draws matches the density ``log_prob`` gives, bin by bin, and the density integrates to 1."""
    net = toy_mdn([[-2.0], [1.5]], [[0.5], [1.0]], [0.3, 0.7])
    history = torch.zeros(200_000, 1)
    x = net.sample(history, torch.Generator().manual_seed(1))[:, 0].numpy()
    assert abs(x.mean() - (0.3 * -2 + 0.7 * 1.5)) < 0.02
    edges = np.linspace(-5, 6, 45)
    centres = torch.tensor((edges[:-1] + edges[1:]) / 2, dtype=torch.float32)[:, None]
    density = torch.exp(net.log_prob(centres, torch.zeros(len(centres), 1))).detach().numpy()
    width = edges[1] - edges[0]
    assert abs(density.sum() * width - 1) < 0.01
    observed = np.histogram(x, edges)[0] / len(x)
    assert np.max(np.abs(observed - density * width)) < 0.006  # 0.25-wide bins: the densest holds about 0.07


def test_a_batch_draws_each_row_as_its_component_alone_would():
    """The sampler groups the rows by their component; every row equals its chosen component's mean plus its
    scale times that row's normals, computed row by row from the full mixture."""
    torch.manual_seed(3)
    net = MDN(5, order=3, hidden=16, layers=2, components=4, n_context=1)
    conditioning = torch.randn(50, 1 + 2 * 5)  # histories of 2 of the 3 frames
    drawn = net.sample(conditioning, torch.Generator().manual_seed(7))
    g = torch.Generator().manual_seed(7)
    u = torch.rand(50, 1, generator=g)
    eps = torch.randn(50, 5, generator=g)
    log_pi, mu, log_s = net.mixture(conditioning)
    for b in range(50):
        cdf = torch.cumsum(torch.exp(log_pi[b]), 0)
        m = min(int((cdf < u[b] * cdf[-1]).sum()), 3)
        expected = mu[b, m] + torch.exp(log_s[b, m]) * eps[b]
        torch.testing.assert_close(drawn[b], expected.detach(), rtol=1e-5, atol=1e-5)


def test_a_short_history_reads_as_training_masks_it():
    """A history of n frames gives the mixture that a full window cut to its last n frames (as training cuts
    it) gives, whatever the masked frames held."""
    torch.manual_seed(4)
    net = MDN(3, order=4, hidden=8, layers=1, components=2)
    full = torch.randn(6, 4 * 3)
    for n in (1, 2, 4):
        short = net.mixture(full[:, -n * 3:])
        masked = net.mixture(full, lengths=torch.full((6,), n))
        for a, b in zip(short, masked):
            torch.testing.assert_close(a, b)
    with pytest.raises(ValueError, match="1 to 4 frames"):
        net.mixture(torch.randn(2, 5 * 3))


@pytest.fixture(scope="module")
def walks(mocap_dir):
    from data_tools.motion.asf_amc import asf_amc_clip
    from data_tools.motion.retarget import retarget

    asf = mocap_dir / "07" / "07.asf"
    return [retarget(asf_amc_clip(asf, mocap_dir / "07" / f"07_{i}.amc"), fps=60).poses for i in ("01", "02")]


SMALL = dict(order=3, hidden=16, layers=1, components=3, epochs=4, batch_size=64, learning_rate=1e-3,
             history_noise="auto", pace_input=None, validation=0.1, checkpoint_every=1)


def train_small(walks, rng_seed: int, **kw) -> NeuralModel:
    from priors.neural.training import train_neural_prior
    from tracker.core.body import fifteen_cone_model
    from tracker.engine.registry import TrainingData

    data = TrainingData(tuple(walks), 60.0, fifteen_cone_model(), ("a", "b"))
    return train_neural_prior(data, {**SMALL, **kw.pop("options", {})}, np.random.default_rng(rng_seed), **kw)


@pytest.mark.slow
def test_training_is_seeded_and_resumes_to_the_same_weights(walks, tmp_path):
    whole = train_small(walks, 1)
    again = train_small(walks, 1)
    other = train_small(walks, 2)
    state = {k: v.clone() for k, v in whole.net.state_dict().items()}
    assert all(torch.equal(state[k], v) for k, v in again.net.state_dict().items())
    assert not all(torch.equal(state[k], v) for k, v in other.net.state_dict().items())
    checkpoint = tmp_path / "model.pt.checkpoint"

    def stop_after_two(epoch, total, values):
        if epoch == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_small(walks, 1, progress=stop_after_two, checkpoint=checkpoint)
    assert checkpoint.exists()
    resumed = train_small(walks, 1, checkpoint=checkpoint, resume=True)
    assert all(torch.equal(state[k], v) for k, v in resumed.net.state_dict().items())
    assert resumed.reconstruction_errors == whole.reconstruction_errors and resumed.best_epoch == whole.best_epoch
    assert not checkpoint.exists()
    with pytest.raises(InputError, match="no training checkpoint"):
        train_small(walks, 1, checkpoint=checkpoint, resume=True)


def test_a_model_file_round_trips_and_a_bad_one_is_refused_in_one_line(walks, tmp_path):
    model = train_small(walks, 3, options={"epochs": 1})
    path = tmp_path / "neural.pt"
    model.save(path)
    back = load_neural(path)
    assert back.config == model.config and back.sources == ["a", "b"] and back.order == 3
    for k, v in model.net.state_dict().items():
        assert torch.equal(v, back.net.state_dict()[k])
    history = torch.randn(20, 2 * model.net.n_features)
    assert torch.equal(model.net.sample(history, torch.Generator().manual_seed(5)),
                       back.net.sample(history, torch.Generator().manual_seed(5)))
    doc = torch.load(path, weights_only=True)
    bad = {"wrong shape": {**doc, "params": {**doc["params"], "logits.bias": torch.zeros(7)}},
           "non-finite": {**doc, "params": {**doc["params"], "means.weight": doc["params"]["means.weight"] * np.nan}},
           "unknown setting": {**doc, "config": {**doc["config"], "depth": 3}},
           "no normaliser": {k: v for k, v in doc.items() if k != "normaliser"},
           "a CRBM's format": {**doc, "format": "pose-tracker crbm v1"}}
    for what, document in bad.items():
        file = tmp_path / f"{what}.pt"
        torch.save(document, file)
        with pytest.raises(InputError) as err:
            load_neural(file)
        assert str(file) in str(err.value) and "\n" not in str(err.value), what


@pytest.mark.slow
def test_the_command_line_tracks_with_a_model_file_and_refuses_a_bad_one_in_one_line(walks, small_walk, tmp_path):
    model = train_small(walks, 3, options={"epochs": 1})
    path = tmp_path / "neural.pt"
    model.save(path)
    run = [sys.executable, "-m", "tracker", "track", str(small_walk), "--prior", "neural", "--particles", "40"]
    r = subprocess.run([*run, "--model", str(path), "--out", str(tmp_path / "t")], capture_output=True, text=True)
    assert r.returncode == 0 and "neural" in r.stdout, r.stderr[-500:]
    text = tmp_path / "notes.pt"
    text.write_text("not a model\n")
    for given, expected in ((text, "not a neural prior model file"), (None, "needs a model file")):
        r = subprocess.run([*run, *(["--model", str(given)] if given else []), "--out", str(tmp_path / "u")],
                           capture_output=True, text=True)
        last = r.stderr.strip().splitlines()[-1]
        assert r.returncode == 2 and expected in last and "Traceback" not in r.stderr, r.stderr[-300:]


@pytest.mark.slow
def test_the_mixture_without_a_model_file_tracks_with_the_shipped_neural_prior(small_walk, tmp_path):
    """The package ships a CMU-trained neural prior (package data) that ``--prior mixture`` uses beside
    zero-velocity when it is given no model file; a model file given still makes the default mixture a CRBM's."""
    from priors.pretrained import mixture_model
    from tracker.app.api import build_prior

    shipped = load_neural(mixture_model())
    assert mixture_model().stat().st_size < 2_000_000 and shipped.order >= 1
    assert shipped.sources and all(s.startswith("cmu/") for s in shipped.sources)  # CMU trials only
    prior = build_prior("mixture", small_walk)
    assert [c.name for c in prior.components] == ["neural", "zero-velocity"]
    r = subprocess.run([sys.executable, "-m", "tracker", "track", str(small_walk), "--prior", "mixture",
                        "--particles", "40", "--out", str(tmp_path / "t")], capture_output=True, text=True)
    assert r.returncode == 0 and "mixture" in r.stdout, r.stderr[-500:]
    record = json.loads((tmp_path / "t" / "result.json").read_text())
    # the record names what ran: the shipped model and its components, not the option's default string
    assert record["prior_options"]["components"] == "neural,zero-velocity"
    assert record["prior_models"] == [str(mixture_model())]


def test_the_shipped_model_predicts_the_roots_motion_of_a_walker_it_never_saw():
    """From the true past of subject 7's walk 07_01 (a person the pretrained model never saw; every 12th frame, 20
    samples each, no ground diffusion), the shipped neural prior's root 20 frames (a third of a second) ahead:
    its ground position within 200 mm of the truth on average (measured 128 mm; a root that stays where it was
    is 455 mm off, one that keeps the last step's velocity 57 mm) and its height within 50 mm (measured 32)."""
    import tracker
    from data_tools.samples import sample_walks
    from priors.neural.prior import NeuralPrior
    from priors.parts import GroundDiffusion
    from priors.pretrained import mixture_model
    from tracker.testing.priors import rollout

    skeleton, walks = sample_walks(7)
    poses = tracker.load_clip(walks[0], skeleton, fps=60.0).poses
    prior = NeuralPrior(load_neural(mixture_model()), ground=GroundDiffusion(0.0))
    order, ahead, samples = prior.order, 20, 20
    ground, height, stays = [], [], []
    for t in range(order, len(poses) - ahead, 12):
        new = rollout(prior, poses[t - order:t], samples, seed=t, frames=ahead)[0][:, -1]
        truth = poses[t - 1 + ahead]
        ground.append(np.linalg.norm(new[:, :2] - truth[:2], axis=1).mean())
        height.append(np.abs(new[:, 2] - truth[2]).mean())
        stays.append(np.linalg.norm(poses[t - 1, :2] - truth[:2]))
    assert np.mean(stays) > 400
    assert np.mean(ground) < 200 and np.mean(height) < 50, (np.mean(ground), np.mean(height))
