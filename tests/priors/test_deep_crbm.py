"""Deep (two-layer) CRBM prior: the second layer's data and training, sampling through both layers, model files,
tracking through the API and the CLI."""
import json

import numpy as np
import pytest
import torch

from priors.crbm.model import CRBM, CRBMConfig
from priors.crbm.training import train_crbm
from priors.deep_crbm.file import load_deep_crbm
from priors.deep_crbm.model import DeepCRBMModel, deep_gibbs
from priors.deep_crbm.prior import DeepCRBMPrior
from priors.deep_crbm.training import first_layer_activations, train_top
from priors.parts import HeightOffset, PostureOffset
from priors.settings import TopConfig
from tracker.core.body import DOF_NAMES
from tracker.core.errors import InputError


@pytest.fixture(scope="module")
def walks():
    """The shipped subject-7 walks at 60 Hz (no shared data needed)."""
    from data_tools.motion.load import load_mocap
    from data_tools.motion.retarget import retarget
    from data_tools.samples import sample_walks

    asf, files = sample_walks()
    return [retarget(load_mocap(f, asf), fps=60).poses for f in files]


@pytest.fixture(scope="module")
def deep(walks):
    rng = np.random.default_rng(0)
    bottom = train_crbm(walks, CRBMConfig(order=2, hidden=20, epochs=20), 60.0, DOF_NAMES, rng=rng)
    acts, follows = first_layer_activations(bottom, walks)
    top, errors = train_top(acts, follows, TopConfig(order=2, hidden=12, epochs=20), rng)
    return DeepCRBMModel(bottom, top, TopConfig(order=2, hidden=12, epochs=20), errors)


def test_second_layer_data_are_the_first_layers_activations(deep, walks):
    acts, follows = first_layer_activations(deep.bottom, walks)
    n = [len(w) - 1 - 2 for w in walks]  # each clip's last frame dropped, 2 frames of history
    assert acts.shape == (sum(n), 20) and float(acts.min()) >= 0 and float(acts.max()) <= 1
    assert not follows[0] and not follows[n[0]] and bool(follows[1:n[0]].all())  # runs restart at each clip
    errs = deep.reconstruction_errors
    assert len(errs) == 20 and errs[-1] < errs[0]


def test_sampling_through_both_layers_batched_equals_looped_and_is_seeded(deep):
    g = torch.Generator().manual_seed(0)
    K = deep.bottom.crbm.n_visible
    hist = torch.randn(10, 4 * K, generator=g)
    batched = deep_gibbs(deep.bottom.crbm, deep.top, hist, 1, None)  # one step: mean-field, no draw
    looped = torch.cat([deep_gibbs(deep.bottom.crbm, deep.top, hist[i:i + 1], 1, None) for i in range(10)])
    assert torch.allclose(batched, looped, atol=1e-5)
    a = deep_gibbs(deep.bottom.crbm, deep.top, hist, 8, torch.Generator().manual_seed(3))
    b = deep_gibbs(deep.bottom.crbm, deep.top, hist, 8, torch.Generator().manual_seed(3))
    c = deep_gibbs(deep.bottom.crbm, deep.top, hist, 8, torch.Generator().manual_seed(4))
    assert torch.equal(a, b) and not torch.equal(a, c) and a.shape == (10, K)


def test_the_prior_grows_its_history_through_the_first_layer(deep, walks):
    prior = DeepCRBMPrior(deep, gibbs_steps=5)
    assert prior.order == 4 and prior.label_for(2) == "crbm order 2" and prior.label_for(4) == "deep crbm order 2+2"
    rng = np.random.default_rng(1)
    state = prior.start(walks[0][:4], 30, rng)
    hist = np.repeat(walks[0][None, :4], 30, axis=0)
    x, state = prior.sample(hist, 4, state, rng)
    assert x.shape == (30, 40) and np.all(np.isfinite(x))
    with pytest.raises(InputError, match="needs 2 known frame"):
        prior.start(walks[0][:1], 30, rng)


@pytest.mark.parametrize("offset", ["height", "posture"])
def test_the_deep_prior_carries_its_offsets_through_both_layers(deep, walks, offset):
    """A particle whose history and height offset are both 60 mm higher (or whose joint angles and posture offset
    are both 0.1 rad larger) samples, through both layers and with the same draws, the same pose 60 mm higher (0.1
    rad larger): the first layer sees the same history."""
    joints = list(range(6, walks[0].shape[1]))
    option, key, entries, dims, shift, summary = {
        "height": ({"height": HeightOffset(40.0)}, "height_offset", slice(None), [2], 60.0, "height offset (mm)"),
        "posture": ({"posture": PostureOffset(0.2)}, "posture_offset", (slice(None), slice(2, None)),  # the joint angles'
                    joints, 0.1, "posture offset rms (deg)")}[offset]
    prior = DeepCRBMPrior(deep, gibbs_steps=5, **option)
    assert prior.summary_names == (summary,)
    out = []
    for lift in (0.0, shift):
        rng = np.random.default_rng(2)
        state = prior.start(walks[0][:4], 20, rng)
        state[key][entries] = lift
        hist = np.repeat(walks[0][None, :4], 20, axis=0)
        hist[..., dims] += lift
        out.append(prior.sample(hist, 4, state, rng)[0])
    assert np.allclose(out[1][:, dims] - out[0][:, dims], shift, atol=1e-5)
    assert np.allclose(np.delete(out[1], dims, axis=1), np.delete(out[0], dims, axis=1), atol=1e-4)


def test_model_file_round_trip_and_broken_files(deep, walks, tmp_path):
    deep.save(tmp_path / "d.pt")
    loaded = load_deep_crbm(tmp_path / "d.pt")
    hist = np.repeat(walks[1][None, 5:9], 20, axis=0)

    def draw(m):
        prior = DeepCRBMPrior(m, gibbs_steps=5)
        rng = np.random.default_rng(2)
        return prior.sample(hist, 4, prior.start(walks[1][:9], 20, rng), rng)[0]

    assert np.array_equal(draw(deep), draw(loaded)) and loaded.order == 4
    with pytest.raises(InputError, match="30 fps .trained at 60 fps"):
        loaded.check_compatible("15-cone", DOF_NAMES, 30.0)
    for damage, expected in [(lambda d: d["top"].__setitem__("A", d["top"]["A"][:3]), "weight A must have shape"),
                             (lambda d: d["top"].__setitem__("W", d["top"]["W"] * float("nan")), "W contains NaN"),
                             (lambda d: d["top"].__setitem__("W", torch.zeros(4)), "weight W must be a 2-D"),
                             (lambda d: d["bottom"]["params"].__setitem__("W", d["bottom"]["params"]["W"][:2]),
                              "CRBM weight A has shape"),
                             (lambda d: d["top_config"].__setitem__("ordr", 2), "unknown settings ordr"),
                             (lambda d: d.pop("top"), "lacks 'top'")]:
        doc = deep.to_document()
        damage(doc)
        torch.save(doc, tmp_path / "bad.pt")
        with pytest.raises(InputError, match=expected) as info:
            load_deep_crbm(tmp_path / "bad.pt")
        assert "bad.pt" in str(info.value), expected
    assert CRBM.PARAMS == ("W", "A", "B", "a", "b")


@pytest.mark.slow
def test_train_and_track_through_the_api_and_the_cli(walk_32_frames, tmp_path, capsys):
    import tracker
    from data_tools.samples import sample_walks
    from tracker.app.cli import main

    asf, files = sample_walks()
    model = tracker.train("deep-crbm", files, skeletons=[asf], order=1, hidden=16, epochs=3, top_order=2,
                          top_hidden=8, top_epochs=3, seed=0)
    assert "second layer order 2" in model.summary()
    model.save(tmp_path / "d.pt")
    res = tracker.track(walk_32_frames, "deep-crbm", models=[tmp_path / "d.pt"], particles=40, frames=6, seed=0,
                        gibbs_steps=4)
    assert res.prior_per_frame == [{"first": 2, "last": 2, "model": "crbm order 1"},
                                   {"first": 3, "last": 5, "model": "deep crbm order 1+2"}]
    assert main(["train", "--prior", "deep-crbm", "--mocap", *map(str, files), "--skeleton", str(asf), "--order",
                 "1", "--hidden", "12", "--epochs", "2", "--top-order", "1", "--top-hidden", "6", "--top-epochs",
                 "2", "--out", str(tmp_path / "c.pt")]) == 0
    assert main(["track", str(walk_32_frames.root), "--prior", "deep-crbm", "--model", str(tmp_path / "c.pt"),
                 "--particles", "30", "--frames", "4", "--gibbs-steps", "3", "--out", str(tmp_path / "t")]) == 0
    result = json.loads((tmp_path / "t" / "result.json").read_text())
    assert result["prior"] == "deep-crbm" and result["frames_tracked"] == 2 and "prior_summary" not in result
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:  # argparse refuses the flag's value
        main(["train", "--prior", "deep-crbm", "--mocap", *map(str, files), "--top-order", "0", "--out",
              str(tmp_path / "e.pt")])
    assert stop.value.code == 2 and "argument --top-order: must be at least 1" in capsys.readouterr().err
