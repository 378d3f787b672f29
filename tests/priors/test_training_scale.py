"""Training that scales with the data: the update budget of the contrastive trainings, labels for clips a labels
pattern leaves out, and the GPDM's subset of a large corpus."""
import numpy as np
import pytest
import torch

from priors.crbm.model import CRBMConfig
from priors.crbm.training import train_crbm, training_windows
from priors.settings import UPDATE_BUDGET, ContrastiveConfig
from tracker.core.body import DOF_NAMES
from tracker.core.errors import InputError


@pytest.fixture(scope="module")
def clips():
    """Two short walks of the shipped samples, retargeted once for the module (120 frames each at 60 Hz)."""
    from dataclasses import replace

    import tracker
    from data_tools.samples import sample_walks

    asf, walks = sample_walks()
    return [replace(c, poses=c.poses[:120], markers=c.markers[:120], model_markers=c.model_markers[:120])
            for c in tracker.load_clips(walks[:2], skeletons=[asf])]


@pytest.fixture(scope="module")
def walk(clips):
    return clips[0].poses


def test_epochs_are_cut_to_the_update_budget_only_where_they_exceed_it():
    cfg = ContrastiveConfig(epochs=500, batch_size=100, updates=25_000)
    assert cfg.epochs_for(5_000) == 500  # 50 mini-batches x 500 epochs: exactly the budget
    assert cfg.epochs_for(5_001) == 491  # 51 mini-batches: ceil(25000 / 51)
    assert cfg.epochs_for(77_000) == 33 and cfg.epochs_for(1) == 500
    assert ContrastiveConfig().updates == UPDATE_BUDGET
    with pytest.raises(InputError, match="updates must be an integer of at least 1"):
        ContrastiveConfig(updates=0).check()


def test_training_windows_counts_what_the_training_trains_on(walk):
    from priors.crbm.training import make_windows, split_validation

    clips = [walk, walk[:80]]
    data = make_windows(clips, 2, DOF_NAMES)
    assert training_windows([len(c) for c in clips], 2, 0.0) == len(data.starts) == (len(walk) - 3) + 77
    kept = split_validation(data.starts, [len(c) for c in clips], 2, 0.2)[0]
    assert training_windows([len(c) for c in clips], 2, 0.2) == len(kept) < len(data.starts)


def test_a_budget_that_does_not_bind_gives_the_same_model_and_one_that_binds_cuts_the_epochs(walk):
    cfg = CRBMConfig(order=1, hidden=8, epochs=6, cd_k=1, batch_size=50)
    windows = training_windows([len(walk)], 1, 0.0)
    batches = -(-windows // 50)
    free = train_crbm([walk], cfg, 60.0, DOF_NAMES, rng=np.random.default_rng(3))
    exact = train_crbm([walk], CRBMConfig(**{**cfg.__dict__, "updates": 6 * batches}), 60.0, DOF_NAMES,
                       rng=np.random.default_rng(3))
    assert all(torch.equal(free.crbm.state_dict()[k], exact.crbm.state_dict()[k]) for k in free.crbm.state_dict())
    assert len(exact.reconstruction_errors) == 6 and exact.config.epochs == 6
    cut = train_crbm([walk], CRBMConfig(**{**cfg.__dict__, "updates": 2 * batches + 1}), 60.0, DOF_NAMES,
                     rng=np.random.default_rng(3))
    assert len(cut.reconstruction_errors) == 3 and cut.config.epochs == 3
    assert cut.reconstruction_errors == free.reconstruction_errors[:3]  # the same draws, stopped sooner


def test_fcrbm_and_deep_crbm_progress_counts_the_cut_epochs(clips):
    import tracker

    small = dict(hidden=8, cd_k=1, seed=0, updates=2, grow_from="none")
    seen = []
    model = tracker.train("fcrbm", clips, labels="a,b", order=1, epochs=50, factors=4, features=2,
                          progress=lambda done, total, _: seen.append((done, total)), **small)
    assert model.config.epochs == len(model.reconstruction_errors) == seen[-1][0] == seen[-1][1] < 50
    seen.clear()
    deep = tracker.train("deep-crbm", clips, order=1, epochs=50, top_order=1, top_hidden=4, top_epochs=50,
                         progress=lambda done, total, _: seen.append((done, total)), **small)
    assert seen[-1][0] == seen[-1][1] == len(deep.bottom.reconstruction_errors) + len(deep.reconstruction_errors) < 100
    assert deep.top_config.epochs == len(deep.reconstruction_errors)


def test_clips_a_labels_pattern_leaves_out_take_the_unlabelled_label(tmp_path):
    from data_tools.motion.corpus import label_source

    source = label_source("dataset-2_{content}_{style}_{take}#style")
    clips = [tmp_path / "dataset-2_walk_elderly_001.bvh", tmp_path / "07_01.amc"]
    with pytest.raises(InputError, match="does not match the labels pattern"):
        source.training_labels(clips)
    assert source.training_labels(clips, "normal") == ["elderly", "normal"]


def test_gpdm_subset_keeps_small_corpora_whole_and_spreads_a_large_one_over_folders():
    from priors.gpdm.subset import MIN_STRETCH, choose_frames

    rng = np.random.default_rng(0)
    assert choose_frames([100, 200], ["a/1", "a/2"], 300, rng) is None
    assert rng.bit_generator.state == np.random.default_rng(0).bit_generator.state  # nothing drawn
    # Stretches of every clip fit: max_frames // clips frames of each, at a random start.
    picked = choose_frames([400, 500, 90], ["a/1", "a/2", "b/1"], 600, np.random.default_rng(1))
    assert [i for i, _, _ in picked] == [0, 1, 2] and [b - a for _, a, b in picked] == [200, 200, 90]
    assert all(0 <= a and b <= n for (_, a, b), n in zip(picked, [400, 500, 90]))
    # Too many clips for a stretch of each: folders in turn, so the one clip of folder b is kept.
    sources = [f"a/{i}" for i in range(20)] + ["b/0"]
    picked = choose_frames([300] * 21, sources, 3 * MIN_STRETCH, np.random.default_rng(2))
    assert len(picked) == 3 and 20 in [i for i, _, _ in picked]
    assert all(b - a == MIN_STRETCH for _, a, b in picked)
    again = choose_frames([300] * 21, sources, 3 * MIN_STRETCH, np.random.default_rng(2))
    assert again == picked


def test_gpdm_trained_on_a_subset_records_it_in_its_file(clips, tmp_path):
    import tracker
    from priors.gpdm.file import load_gpdm_prior

    model = tracker.train("gpdm", clips, iterations=2, max_frames=120, seed=0)
    assert model.subset is not None and sum(s.stop - s.start for s in model.subset) == len(model.gpdm.Y) + 2
    assert "a subset: 2 stretch(es) of 2 clip(s)" in model.summary()
    model.save(tmp_path / "g.pt")
    back = load_gpdm_prior(tmp_path / "g.pt")
    assert back.subset == model.subset and back.corpus_frames == model.corpus_frames > 120


def stopped_then_resumed(prior, clips, stop, checkpoint, settings):
    """``prior`` trained on ``clips`` stopped (Ctrl-C) at its ``stop``-th progress call with ``checkpoint``, then
    resumed from it: the resumed model."""
    import tracker

    calls = []

    def interrupt(done, total, metrics):
        calls.append(done)
        if len(calls) == stop:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        tracker.train(prior, clips, checkpoint=checkpoint, progress=interrupt, **settings)
    assert checkpoint.exists()
    return tracker.train(prior, clips, checkpoint=checkpoint, resume=True, **settings)


@pytest.mark.parametrize("prior, stop", [("fcrbm", 5), ("crbm", 2)])  # in the order-3 stage; in the growth stage
def test_an_interrupted_training_resumes_to_the_same_model(prior, stop, clips, tmp_path):
    import tracker

    settings = dict(order=3, epochs=3, hidden=8, cd_k=2, seed=0, checkpoint_every=1)
    if prior == "fcrbm":
        settings.update(labels="a,b", factors=4, features=2)
    whole = tracker.train(prior, clips, **settings)
    resumed = stopped_then_resumed(prior, clips, stop, tmp_path / "c.pt", settings)
    net = (lambda m: m.fcrbm) if prior == "fcrbm" else (lambda m: m.crbm)
    for a, b in [(whole, resumed), (whole.growth[0], resumed.growth[0])]:
        assert all(torch.equal(v, net(b).state_dict()[k]) for k, v in net(a).state_dict().items())
        assert a.reconstruction_errors == b.reconstruction_errors
    assert not (tmp_path / "c.pt").exists()


@pytest.mark.parametrize("stop", [2, 7])  # in the first layer's order-1 stage; in the second layer
def test_an_interrupted_deep_crbm_training_resumes_to_the_same_model(stop, clips, tmp_path):
    import tracker

    settings = dict(order=2, epochs=2, hidden=8, cd_k=2, top_order=1, top_hidden=4, top_epochs=4,
                    seed=0, checkpoint_every=1)
    whole = tracker.train("deep-crbm", clips, **settings)
    resumed = stopped_then_resumed("deep-crbm", clips, stop, tmp_path / "c.pt", settings)
    for a, b in [(whole.bottom.crbm, resumed.bottom.crbm), (whole.bottom.growth[0].crbm, resumed.bottom.growth[0].crbm),
                 (whole.top, resumed.top)]:
        assert all(torch.equal(v, b.state_dict()[k]) for k, v in a.state_dict().items())
    assert whole.reconstruction_errors == resumed.reconstruction_errors and not (tmp_path / "c.pt").exists()
