"""The motion-prior contract (:class:`tracker.testing.PriorContract`), run for every registered prior of the
package.

Every prior the registry knows is built through the public API from small models trained here, in each
configuration of ``BUILT`` below, and checked by the contract's tests (a plugin's own tests inherit the same
class: tests/plugin_example). A prior of the package that has no configuration in ``BUILT`` fails the tests: a
new prior joins the contract by being added there.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from tracker.testing import PriorContract


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
        "neural": tracker.train("neural", walks[:1], order=3, hidden=16, layers=1, epochs=2, seed=5),
        "neural-paced": tracker.train("neural", walks, order=2, hidden=16, layers=1, epochs=2, seed=6),
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
             ("crbm", ["crbm"], {"height_spread": 30.0, "height_drift": 1.0, "posture_gain": 0.2}),
             ("crbm", ["crbm-paced"], {"height_spread": 30.0, "height_drift": 1.0, "posture_gain": 0.2})],
    "gpdm": [("gpdm", ["gpdm"], {}), ("gpdm", ["gpdm"], {"height_drift": 2.0}),
             ("gpdm", ["gpdm"], {"posture_gain": 0.2}), ("gpdm", ["gpdm"], {"height_drift": 2.0, "posture_gain": 0.2})],
    "fcrbm": [("fcrbm", ["fcrbm"], {}), ("fcrbm", ["fcrbm"], {"style": "b"}),
              ("fcrbm", ["fcrbm"], {"height_spread": 20.0, "height_drift": 1.0, "posture_gain": 0.2})],
    "deep-crbm": [("deep-crbm", ["deep-crbm"], {"height_spread": 20.0}),
                  ("deep-crbm", ["deep-crbm"], {"height_spread": 20.0, "height_drift": 1.0, "posture_gain": 0.2})],
    "neural": [("neural", ["neural"], {}),
               ("neural", ["neural-paced"], {"height_spread": 30.0, "height_drift": 1.0, "posture_gain": 0.2})],
    "mixture": [("mixture", ["crbm-paced"], {}), ("mixture", ["crbm", "gpdm"], {"components": "crbm,gpdm"}),
                ("mixture", ["fcrbm", "deep-crbm"], {"components": "fcrbm,deep-crbm"}),
                ("mixture", [], {"components": "zero-velocity,constant-velocity", "switch": 0.2})],
}
CONFIGURATIONS = [c for configurations in BUILT.values() for c in configurations]
LABELS = [f"{name}-{'+'.join(files) or 'none'}-{k}" for k, (name, files, _) in enumerate(CONFIGURATIONS)]
#: Priors without lower orders to grow their history through.
RANDOM_WALKS = ("zero-velocity", "constant-velocity")


#: The parts each learned prior of the package takes (every one that applies to its model's features).
LEARNED_PARTS = {"crbm": ("GroundDiffusion", "PaceInput", "HeightOffset", "PostureOffset"),
                 "fcrbm": ("GroundDiffusion", "HeightOffset", "PostureOffset"),
                 "deep-crbm": ("GroundDiffusion", "HeightOffset", "PostureOffset"),
                 "gpdm": ("GroundDiffusion", "HeightOffset", "PostureOffset"),
                 "neural": ("GroundDiffusion", "PaceInput", "HeightOffset", "PostureOffset")}


@pytest.mark.slow
def test_every_learned_prior_is_checked_with_every_part_it_takes_switched_on(built):
    """The contract checks each part through the part protocol (:meth:`TestRegisteredPriors.parts`): some
    configuration of each learned prior has all its parts in use."""
    for name, expected in LEARNED_PARTS.items():
        found = [sorted(type(p).__name__ for p in getattr(built(k), "parts", ()))
                 for k, (prior, _, _) in enumerate(CONFIGURATIONS) if prior == name]
        assert sorted(expected) in found, f"no configuration of {name} uses all of {expected}: {found}"


@pytest.mark.slow
def test_every_learned_prior_names_its_parts_in_use_by_kind(built):
    """Each learned prior answers ``ground``, ``pace``, ``height`` and ``posture`` alike: the part in use of that
    kind, or None."""
    from priors.learned import LearnedPrior
    from priors.parts import GroundDiffusion, HeightOffset, PaceInput, PostureOffset

    kinds = {"ground": GroundDiffusion, "pace": PaceInput, "height": HeightOffset, "posture": PostureOffset}
    learned = [built(k) for k in range(len(CONFIGURATIONS)) if isinstance(built(k), LearnedPrior)]
    assert {p.name for p in learned} >= set(LEARNED_PARTS)
    for prior in learned:
        for name, kind in kinds.items():
            assert getattr(prior, name) is prior.part(kind), f"{prior.name}.{name}"


def test_every_registered_prior_of_the_package_has_a_contract_configuration():
    from tracker.app.api import available_priors, prior_entry

    names = [n for n in available_priors() if prior_entry(n).build.__module__.startswith("priors.")]
    missing = sorted(set(names) - set(BUILT))
    assert not missing, f"registered priors without a contract configuration: {missing}"


@pytest.fixture(scope="module")
def built(models, walk_07_01):
    """The prior of configuration ``k`` of :data:`CONFIGURATIONS`, built through the API on first use."""
    from tracker.app.api import build_prior
    from tracker.core.representation import step_rms

    class _Seq:  # what build_prior reads of a sequence
        model = walk_07_01.model
        fps = 60.0
        root = Path("contract")

    step_std = step_rms([walk_07_01.poses])
    cache = {}

    def get(k: int):
        if k not in cache:
            name, files, options = CONFIGURATIONS[k]
            cache[k] = build_prior(name, _Seq(), [models[f] for f in files], step_std=step_std, **options)
        return cache[k]
    return get


def members(prior) -> list:
    """The priors a composite prior samples with (a mixture's components), or the prior itself."""
    return list(getattr(prior, "components", None) or [prior])


@pytest.mark.slow
class TestRegisteredPriors(PriorContract):
    """Every configuration of :data:`BUILT`, started from the realistic walk 07_01."""

    @pytest.fixture(autouse=True, params=range(len(CONFIGURATIONS)), ids=LABELS)
    def configuration(self, request, built, walk_07_01):
        self.prior = built(request.param)
        self.poses = walk_07_01.poses

    def make_prior(self):
        return self.prior

    def known_poses(self):
        return self.poses

    def components(self, prior, state):
        """A mixture's components, or an ensemble's members (each samples its particles with its own model)."""
        found = super().components(prior, state)
        if found is None and isinstance(state, dict) and "component" in state:
            return np.asarray(state["component"])
        return found

    def frames_before_batch_check(self, prior):
        """0 for a prior with a posture offset: that offset is one for the whole particle set (it integrates
        the posterior's mean posture correction, :class:`priors.parts.PostureOffset`), the one part that sees
        the other particles by design; before its first move it sees none."""
        return 0 if any(getattr(m, "posture", None) is not None for m in members(prior)) else 2

    def grows_history(self, prior):
        return prior.order >= 2 and not all(m.name in RANDOM_WALKS for m in members(prior))

    def parts(self, prior):
        """A learned prior's parts in use (:class:`priors.learned.LearnedPrior`), each checked through the part
        protocol; none for the others (a mixture's components are checked as priors of their own)."""
        from priors.learned import LearnedPrior

        return list(prior.parts) if isinstance(prior, LearnedPrior) else []


def test_model_files_of_0_13_sample_as_they_did(walk_07_01):
    """A paced CRBM-3 and a GPDM saved by pose-tracker 0.13.0 (tests/data) load, and at their defaults draw, from
    the same seed, the poses 0.13.0 drew (``samples_v0.13.npy``: 4 steps of 8 particles from 07_01's first
    frames; the defaults' numbers did not change when the priors became a model plus parts)."""
    from tracker.app.api import build_prior

    data = Path(__file__).parents[1] / "data"
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
