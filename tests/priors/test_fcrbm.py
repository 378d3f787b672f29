"""FCRBM prior: free-energy gradients (the CD statistics), sampling, determinism, model files, labels, style
inference while tracking (API and CLI), and sequences that change activity."""
import json
import subprocess
import sys

import numpy as np
import pytest
import torch

from priors.fcrbm.file import load_fcrbm
from priors.fcrbm.model import FCRBM, FCRBMConfig, group_rows, parse_labels
from priors.fcrbm.prior import FCRBMPrior, generate, transition_styles
from priors.fcrbm.training import train_fcrbm
from tracker.core.body import DOF_NAMES
from tracker.core.errors import InputError


@pytest.fixture(scope="module")
def s2(mocap_dir):
    """Subject 2's folder (walks 02_01, 02_02, run 02_03), or a skip."""
    if not all((mocap_dir / "02" / f).exists() for f in ("02.asf", "02_01.amc", "02_03.amc")):
        pytest.skip(f"subject 2's walk and run are not in {mocap_dir / '02'}")
    return mocap_dir / "02"


@pytest.fixture(scope="module")
def clips(s2):
    """Subject 2: a walk and a run at 60 Hz."""
    from data_tools.motion.asf_amc import asf_amc_clip
    from data_tools.motion.retarget import retarget

    return [retarget(asf_amc_clip(s2 / "02.asf", s2 / f), fps=60).poses for f in ("02_01.amc", "02_03.amc")]


@pytest.fixture(scope="module")
def model(clips):
    return train_fcrbm(clips, ["walk", "run"], FCRBMConfig(order=2, hidden=24, factors=12, features=4, epochs=30),
                       60.0, DOF_NAMES, rng=np.random.default_rng(0))


def tiny_fcrbm(seed: int = 0) -> FCRBM:
    """A small float64 FCRBM with every parameter non-zero (K=5, H=7, N=2, P=3 labels, L=4, F=6)."""
    g = torch.Generator().manual_seed(seed)
    net = FCRBM(5, 7, 2, 3, 4, 6, generator=g, dtype=torch.float64)
    for k, v in net.params.items():
        net.params[k] = v + 0.3 * torch.randn(v.shape, generator=g, dtype=torch.float64)
    return net


def test_free_energy_gradients_match_finite_differences():
    net = tiny_fcrbm()
    g = torch.Generator().manual_seed(1)
    v = torch.randn(9, 5, generator=g, dtype=torch.float64)
    hist = torch.randn(9, 10, generator=g, dtype=torch.float64)
    y = torch.softmax(torch.randn(9, 3, generator=g, dtype=torch.float64), 1)  # blends, not only one-hot
    grads = net.free_energy_gradients(v, hist, y)
    eps = 1e-6
    for k in FCRBM.PARAMS:
        p = net.params[k].view(-1)
        numeric = torch.zeros_like(p)
        for i in range(len(p)):
            old = float(p[i])
            p[i] = old + eps
            up = net.free_energy(v, hist, y).mean()
            p[i] = old - eps
            down = net.free_energy(v, hist, y).mean()
            p[i] = old
            numeric[i] = (up - down) / (2 * eps)
        assert torch.allclose(numeric, grads[k].reshape(-1), atol=1e-7), k
    # The autoregressive share of the tied Z: the gradient with the other two sub-models switched off.
    ar = grads["Z_autoregressive"]
    net.params["Wv"].zero_()
    net.params["Bp"].zero_()
    assert torch.allclose(net.free_energy_gradients(v, hist, y)["Z"], ar, atol=1e-12)


def test_grouped_sampling_equals_factored_and_batched_equals_looped():
    net = tiny_fcrbm(2)
    g = torch.Generator().manual_seed(3)
    hist = torch.randn(12, 10, generator=g, dtype=torch.float64)
    labels = torch.tensor([0, 1, 2, 1, 0, 0, 2, 1, 1, 2, 0, 1])
    for y in (torch.eye(3, dtype=torch.float64)[labels], torch.softmax(torch.randn(12, 3, generator=g,
                                                                                   dtype=torch.float64), 1)):
        grouped = net.gibbs(hist, y, 6, torch.Generator().manual_seed(5), grouped=True)
        factored = net.gibbs(hist, y, 6, torch.Generator().manual_seed(5), grouped=False)
        assert torch.allclose(grouped, factored, atol=1e-12)
    y = torch.eye(3, dtype=torch.float64)[labels]
    batched = net.gibbs(hist, y, 1, None)  # one step is the mean-field prediction: no random draw
    looped = torch.cat([net.gibbs(hist[i:i + 1], y[i:i + 1], 1, None) for i in range(12)])
    assert torch.allclose(batched, looped, atol=1e-12)


def test_style_rows_are_grouped_as_torch_unique_groups_them():
    g = torch.Generator().manual_seed(4)
    for y in (torch.eye(3)[torch.randint(0, 3, (200,), generator=g)],
              torch.randint(0, 3, (300, 4), generator=g).float() / 2,  # rows equal in leading columns, not later ones
              torch.tensor([[0.5, 0.5]]), torch.rand(50, 3, generator=g)):
        styles, inverse, order = group_rows(y)
        expected_styles, expected_inverse = torch.unique(y, dim=0, return_inverse=True)
        assert torch.equal(styles, expected_styles) and torch.equal(inverse, expected_inverse)
        assert torch.equal(order, torch.argsort(expected_inverse, stable=True))


def test_training_is_deterministic_per_seed_and_lowers_the_error(clips):
    cfg = FCRBMConfig(order=1, hidden=10, factors=6, features=3, epochs=12)
    a = train_fcrbm(clips, ["walk", "run"], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(4))
    b = train_fcrbm(clips, ["walk", "run"], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(4))
    c = train_fcrbm(clips, ["walk", "run"], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(5))
    assert all(torch.equal(a.fcrbm.params[k], b.fcrbm.params[k]) for k in FCRBM.PARAMS)
    assert not torch.equal(a.fcrbm.params["Wv"], c.fcrbm.params["Wv"])
    errs = a.reconstruction_errors
    assert len(errs) == 12 and errs[-1] < 0.7 * errs[0]


def test_prior_sampling_is_deterministic_and_the_posterior_is_the_labels_histogram(model, clips):
    prior = FCRBMPrior([model], gibbs_steps=5)
    hist = np.repeat(clips[0][None, 10:12], 300, axis=0)

    def draw(seed):
        rng = np.random.default_rng(seed)
        state = prior.start(clips[0][:12], 300, rng)
        return state, *prior.sample(hist, 2, state, rng)

    s0, x0, n0 = draw(7)
    _, x1, n1 = draw(7)
    _, x2, _ = draw(8)
    assert np.array_equal(x0, x1) and np.array_equal(n0["style"], n1["style"]) and not np.array_equal(x0, x2)
    w = np.where(n0["style"] == 0, 3.0, 1.0)
    w /= w.sum()
    post = prior.summarize(n0, w)
    assert post.shape == (2,) and np.isclose(post.sum(), 1) and np.isclose(post[0], w[n0["style"] == 0].sum())
    oracle = FCRBMPrior([model], gibbs_steps=5, style="run")
    state = oracle.start(clips[0][:12], 50, np.random.default_rng(0))
    _, state = oracle.sample(hist[:50], 2, state, np.random.default_rng(0))
    assert np.all(state["style"] == 1) and np.allclose(oracle.summarize(state, np.full(50, 0.02)), [0, 1])
    with pytest.raises(InputError, match="not a label of this FCRBM"):
        FCRBMPrior([model], style="jump")


def test_mixture_inference_keeps_a_share_of_particles_on_every_label(model, clips):
    prior = FCRBMPrior([model], gibbs_steps=5, style_switch=0.1, style_temperature=20)
    assert prior.settings()["style_temperature"] == 20
    rng = np.random.default_rng(0)
    state = prior.start(clips[0][:12], 9, rng)
    assert list(state["style"]) == [0, 1, 0, 1, 0, 1, 0, 1, 0]  # particle i carries label i mod L
    _, after = prior.sample(np.repeat(clips[0][None, 10:12], 9, axis=0), 2, state, rng)
    assert np.array_equal(after["style"], state["style"])  # the labels never switch on their own
    mix = prior.mixing().at(prior.component_of(after))
    assert np.array_equal(mix.component, after["style"]) and mix.temperature == 20
    assert np.allclose(mix.transition, [[0.9, 0.1], [0.1, 0.9]])
    moved = prior.relabel(prior.reindex(after, np.zeros(9, int)), mix.component)
    assert np.array_equal(moved["style"], state["style"]) and np.all(moved["clock"] == after["clock"])
    assert FCRBMPrior([model], style="run").mixing() is None  # an oracle has nothing to infer
    with pytest.raises(InputError, match="style temperature"):
        FCRBMPrior([model], style_temperature=0.5)


def test_a_style_schedule_gives_each_frame_its_label_and_survives_a_restart(model, clips):
    oracle = FCRBMPrior([model], gibbs_steps=2, style="walk,run@14,walk@16")
    rng = np.random.default_rng(0)
    state = oracle.start(clips[0][:12], 20, rng)  # the first tracked frame is 12
    hist = np.repeat(clips[0][None, 10:12], 20, axis=0)
    labels = []
    for _ in range(5):  # frames 12..16
        _, state = oracle.sample(hist, 2, state, rng)
        labels.append(oracle.labels[int(state["style"][0])])
        assert np.all(state["style"] == state["style"][0])
    assert labels == ["walk", "walk", "run", "run", "walk"] and np.all(state["clock"] == 17)
    # the filter lost the person at frame 17: the clock goes on to 18 (a plain start would restart it at 2)
    restarted = oracle.restart(state, clips[0][15:17], 20, rng)
    assert np.all(restarted["clock"] == 18) and oracle.labels[int(restarted["style"][0])] == "walk"
    assert oracle.settings()["style"] == "walk,run@14,walk@16"
    for bad, expected in [("walk@3", "holds from frame 0"), ("walk,run", "label@frame"), ("walk,run@x", "label@frame"),
                          ("walk,run@5,walk@5", "must increase"), ("walk,jump@4", "not a label")]:
        with pytest.raises(InputError, match=expected):
            FCRBMPrior([model], style=bad)


def test_generation_with_fixed_styles_and_a_transition(model, clips):
    start = clips[0][:3]
    walk = generate(model, start, transition_styles(2, 0, 0, 40, 0, 1), np.random.default_rng(0), gibbs_steps=10)
    ramp = transition_styles(2, 0, 1, 40, 10, 20)
    assert np.allclose(ramp.sum(1), 1) and ramp[9, 0] == 1 and ramp[30, 1] == 1 and 0 < ramp[20, 1] < 1
    moved = generate(model, start, ramp, np.random.default_rng(0), gibbs_steps=10)
    assert walk.shape == moved.shape == (40, 40) and np.all(np.isfinite(moved))
    assert np.array_equal(walk[:10], moved[:10])  # identical draws until the labels differ
    with pytest.raises(InputError, match="one column per label"):
        generate(model, start, np.ones((5, 3)), np.random.default_rng(0))


def test_model_file_round_trip(model, clips, tmp_path):
    model.save(tmp_path / "f.pt")
    loaded = load_fcrbm(tmp_path / "f.pt")
    assert loaded.labels == ["walk", "run"] and loaded.clip_labels == ["walk", "run"] and loaded.fps == 60.0
    hist = np.repeat(clips[1][None, 5:7], 64, axis=0)

    def draw(m):
        prior = FCRBMPrior([m], gibbs_steps=5)
        rng = np.random.default_rng(3)
        return prior.sample(hist, 2, prior.start(clips[1][:7], 64, rng), rng)[0]

    assert np.array_equal(draw(model), draw(loaded))
    with pytest.raises(InputError, match="30 fps .trained at 60 fps"):
        loaded.check_compatible("15-cone", DOF_NAMES, 30.0, tmp_path / "f.pt")
    with pytest.raises(InputError, match="a different pose layout"):
        loaded.check_compatible("15-cone", list(DOF_NAMES[:-1]) + ["x"], 60.0)


@pytest.mark.parametrize("damage, expected", [
    (lambda d: d["params"].__setitem__("Wv", d["params"]["Wv"] * float("nan")), "Wv contains NaN"),
    (lambda d: d["params"].__setitem__("Ap", d["params"]["Ap"][:5]), "weight Ap has shape"),
    (lambda d: d["params"].__setitem__("R", d["params"]["R"][:1]), "weight R has shape"),
    (lambda d: d["params"].__setitem__("Wv", torch.zeros(4)), "weight Wv must be 2-D"),
    (lambda d: d.__setitem__("labels", ["walk", "walk"]), "repeated or malformed"),
    (lambda d: d.__setitem__("labels", []), "non-empty list"),
    (lambda d: d.__setitem__("clip_labels", ["walk", "jump"]), "clip labels do not match"),
    (lambda d: d["config"].__setitem__("factorz", 3), "unknown settings factorz"),
    (lambda d: d.pop("normaliser"), "lacks 'normaliser'"),
    (lambda d: d.__setitem__("fps", "sixty"), "fps must be a number"),
])
def test_broken_model_files_are_refused(model, tmp_path, damage, expected):
    doc = model.to_document()
    damage(doc)
    torch.save(doc, tmp_path / "bad.pt")
    with pytest.raises(InputError, match=expected) as info:
        load_fcrbm(tmp_path / "bad.pt")
    assert "bad.pt" in str(info.value) and "\n" not in str(info.value)


def test_bad_label_sets_are_refused(clips):
    assert parse_labels("walk, run", ["a.amc", "b.amc"]) == ["walk", "run"]
    assert parse_labels(["walk", "run"], ["a.amc", "b.amc"]) == parse_labels("['walk', 'run']", ["a", "b"])
    with pytest.raises(InputError, match="1 label.s. given for 2 training clip"):
        parse_labels("walk", ["a.amc", "b.amc"])
    with pytest.raises(InputError, match="is not a label") as info:
        parse_labels("walk,r u n", ["a.amc", "b.amc"])
    assert "b.amc" in str(info.value)
    short = [clips[0], clips[1][:3]]
    with pytest.raises(InputError, match="label 'run' has no clip longer than"):
        train_fcrbm(short, ["walk", "run"], FCRBMConfig(order=2, epochs=1), 60.0, DOF_NAMES,
                    sources=["02_01.amc", "02_03.amc"], rng=np.random.default_rng(0))


@pytest.mark.slow
def test_train_and_track_through_the_api(s2, walk_32_frames, tmp_path):
    import tracker

    files = [s2 / "02_01.amc", s2 / "02_03.amc"]
    model = tracker.train("fcrbm", files, labels="walk,run", order=2, epochs=4, hidden=16, factors=8, features=3,
                          seed=0)
    assert [g.order for g in model.growth] == [1] and "labels walk, run" in model.summary()
    model.save(tmp_path / "f.pt")
    res = tracker.track(walk_32_frames, "fcrbm", models=[tmp_path / "f.pt"], particles=60, frames=6, seed=0,
                        gibbs_steps=5)
    again = tracker.track(walk_32_frames, "fcrbm", models=[tmp_path / "f.pt"], particles=60, frames=6, seed=0,
                          gibbs_steps=5)
    assert np.array_equal(res.poses, again.poses)
    out = res.save(tmp_path / "run")
    summary = json.loads((tmp_path / "run" / "result.json").read_text())["prior_summary"]
    assert out["prior_summary"] == summary and summary["names"] == ["walk", "run"] and summary["first_frame"] == 2
    rows = np.array(summary["per_frame"])
    assert rows.shape == (4, 2) and np.allclose(rows.sum(1), 1, atol=1e-3)
    assert summary["most_probable"] == [["walk", "run"][k] for k in rows.argmax(1)]
    assert out["prior_settings"]["labels"] == ["walk", "run"] and out["prior_settings"]["style_switch"] == 0.05
    with pytest.raises(InputError, match="one label per training clip"):
        tracker.train("fcrbm", files, epochs=1)


@pytest.mark.slow
def test_mixture_inference_is_annealed_by_default_and_plain_when_asked(s2, walk_32_frames, tmp_path):
    import tracker

    files = [s2 / "02_01.amc", s2 / "02_03.amc"]
    tracker.train("fcrbm", files, labels="walk,run", order=1, epochs=2, hidden=10, factors=5, features=3,
                  seed=0).save(tmp_path / "f.pt")
    models = [tmp_path / "f.pt"]
    res = tracker.track(walk_32_frames, "fcrbm", models=models, particles=40, frames=4, seed=0)
    plain = tracker.track(walk_32_frames, "fcrbm", models=models, particles=40, frames=4, seed=0,
                          annealing_layers=1)
    assert res.settings["annealing_layers"] == 3 and plain.settings["annealing_layers"] == 1
    assert not np.array_equal(res.poses, plain.poses)
    for run in (res, plain):
        rows = np.array(run.prior_summary["per_frame"])
        assert rows.shape == (2, 2) and np.allclose(rows.sum(1), 1, atol=1e-3)


@pytest.mark.slow
def test_train_and_track_through_the_cli(s2, walk_32_frames, tmp_path, capsys):
    from tracker.app.cli import main

    model = tmp_path / "f.pt"
    amc = [str(s2 / f) for f in ("02_01.amc", "02_03.amc")]
    r = subprocess.run([sys.executable, "-m", "tracker", "--threads", "1", "train", "--prior", "fcrbm", "--mocap",
                        *amc, "--labels", "walk,run", "--order", "1", "--epochs", "3", "--hidden", "12",
                        "--factors", "6", "--features", "3", "--out", str(model)], capture_output=True, text=True)
    assert r.returncode == 0 and "FCRBM order 1" in r.stdout, r.stderr[-500:]
    assert main(["track", str(walk_32_frames.root), "--prior", "fcrbm", "--model", str(model), "--particles", "40",
                 "--frames", "5", "--gibbs-steps", "3", "--style-switch", "0.1", "--out", str(tmp_path / "t")]) == 0
    result = json.loads((tmp_path / "t" / "result.json").read_text())
    assert result["prior"] == "fcrbm" and len(result["prior_summary"]["per_frame"]) == 3
    assert (tmp_path / "t" / "prior_summary.png").stat().st_size > 1000
    capsys.readouterr()
    for args, expected in [(["train", "--prior", "fcrbm", "--mocap", *amc, "--labels", "walk", "--out",
                             str(tmp_path / "other.pt")],
                            "1 label(s) given for 2 training clip(s)"),
                           (["track", str(walk_32_frames.root), "--prior", "fcrbm", "--model", str(model),
                             "--style", "jump", "--out", str(tmp_path / "u")], "not a label of this FCRBM")]:
        assert main(args) == 2, args
        err = capsys.readouterr().err.strip()
        assert expected in err and "\n" not in err and "Traceback" not in err, (args, err)


@pytest.mark.slow
def test_cross_faded_sequence_changes_activity(s2, tmp_path):
    import tracker
    from data_tools.motion.transition import cross_fade

    walk = tracker.load_clip(s2 / "02_01.amc", fps=30)
    run = tracker.load_clip(s2 / "02_03.amc", fps=30)
    clip, change = cross_fade(walk, run, 60, fade=10)
    assert change.fade_start == 50 and change.switch == 60
    assert np.allclose(clip.poses[:50], walk.poses[:50], atol=1e-6)  # the walk itself until the fade
    speed = np.linalg.norm(np.diff(clip.poses[:, :2], axis=0), axis=1)
    assert speed[60:].mean() > 1.8 * speed[:50].mean()  # running: more than twice as fast on the ground
    assert speed.max() < 1.5 * speed[60:].max()  # no jump at the fade
    with pytest.raises(InputError, match="switch_at must be a frame"):
        cross_fade(walk, run, 5, fade=10)
    seq = tracker.synthesize(s2 / "02_01.amc", tmp_path / "s", fps=30, then=run, switch_at=60,
                             fade=10, start=45, frames=20, cameras=1, width=160, height=120)
    assert seq.n_frames == 20 and "02_03" in json.loads((tmp_path / "s" / "meta.json").read_text())["source"]
    with pytest.raises(InputError, match="needs switch_at"):
        tracker.synthesize(s2 / "02_01.amc", tmp_path / "t", fps=30, then=run, frames=5)
