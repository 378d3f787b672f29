"""The motion-prior contract (:class:`tracker.testing.PriorContract`), run for every registered prior of the
package.

Every prior the registry knows is built through the public API and checked by the contract's tests (a plugin's
own tests inherit the same class: tests/plugin_example). A learned prior (:class:`priors.learned.LearnedPrior`)
is built from the small models it declares (:attr:`~priors.learned.LearnedPrior.SMALL_MODELS`, trained here), at
its defaults and with every part it declares (:attr:`~priors.learned.LearnedPrior.PARTS`) switched on: a new
learned prior joins the contract by being registered. The other priors, and further configurations of the
learned ones, are listed in ``EXTRA``; a prior of the package with no configuration fails the tests.
"""
from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
import pytest
import torch

from tracker.testing import PriorContract

#: The walks the small models train on, of different people (so that their paces vary), in this order.
WALKS = ("07/07_01.amc", "02/02_01.amc", "91/91_straight_walk.amc")
#: Options that stand for "every part the prior declares switched on" (:func:`parts_switched_on`).
PARTS_ON = "parts on"


def package_priors() -> list[str]:
    """The names of the priors the package registers (not a plugin's)."""
    from tracker.app.api import available_priors, prior_entry

    return [n for n in available_priors() if prior_entry(n).build.__module__.startswith("priors.")]


def learned_priors() -> dict[str, type]:
    """The learned priors the package registers: name -> the concrete :class:`~priors.learned.LearnedPrior`
    subclass of the package of that name."""
    from priors.learned import LearnedPrior

    names = package_priors()  # imports the modules that define them
    found, stack = {}, [LearnedPrior]
    while stack:
        cls = stack.pop()
        stack.extend(cls.__subclasses__())
        if not inspect.isabstract(cls) and cls.__module__.startswith("priors."):
            found.setdefault(cls.name, cls)
    return {name: found[name] for name in names if name in found}


def model_key(name: str, small) -> str:
    """The key of a prior's small model (:class:`~priors.learned.SmallModel`) among the trained files."""
    return f"{name}-{small.label}" if small.label else name


LEARNED = learned_priors()


@pytest.fixture(scope="module")
def models(mocap_dir, tmp_path_factory):
    """The small models every learned prior declares, trained once through the API: key -> (file, whether the
    model takes a pace input)."""
    import tracker
    from priors.learned import is_paced

    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("contract_models")
    walks = [mocap_dir / w for w in WALKS]
    files, seed = {}, 0
    for name, cls in LEARNED.items():
        for small in cls.SMALL_MODELS:
            key = model_key(name, small)
            model = tracker.train(name, walks[:small.clips], seed=seed, **small.options)
            files[key] = (out / f"{key}.pt", is_paced(model))
            model.save(files[key][0])
            seed += 1
    return files


def parts_switched_on(cls, paced: bool) -> dict:
    """Option values that switch on every part ``cls`` declares (the pace only for a model with a pace input): an
    option's own default where it is on, else a hundredth of its maximum."""
    return {o.name: o.default or o.maximum / 100 for spec in cls.PARTS if paced or not spec.paced
            for o in spec.options()}


#: Configurations besides the learned priors' own (their defaults and their parts switched on): the priors that
#: are not learned, and further settings of learned ones. (registered name, model files, options).
EXTRA = {
    "zero-velocity": [("zero-velocity", [], {})],
    "constant-velocity": [("constant-velocity", [], {})],
    "crbm": [("crbm", ["crbm", "crbm"], {}), ("crbm", ["crbm"], {"height_spread": 30.0, "height_drift": 1.0})],
    "gpdm": [("gpdm", ["gpdm"], {"height_drift": 2.0}), ("gpdm", ["gpdm"], {"posture_gain": 0.2})],
    "fcrbm": [("fcrbm", ["fcrbm"], {"style": "b"})],
    "deep-crbm": [("deep-crbm", ["deep-crbm"], {"height_spread": 20.0})],
    "mixture": [("mixture", ["crbm-paced"], {}), ("mixture", ["crbm", "gpdm"], {"components": "crbm,gpdm"}),
                ("mixture", ["fcrbm", "deep-crbm"], {"components": "fcrbm,deep-crbm"}),
                ("mixture", [], {"components": "zero-velocity,constant-velocity", "switch": 0.2})],
}
#: How each registered prior is built for the contract: (registered name, model files, options).
BUILT = {name: [(name, [model_key(name, small)], options) for small in cls.SMALL_MODELS
                for options in ({}, PARTS_ON)] for name, cls in LEARNED.items()}
for _name, _extra in EXTRA.items():
    BUILT[_name] = BUILT.get(_name, []) + _extra
CONFIGURATIONS = [c for configurations in BUILT.values() for c in configurations]
LABELS = [f"{name}-{'+'.join(files) or 'none'}-{'parts-on' if options == PARTS_ON else k}"
          for k, (name, files, options) in enumerate(CONFIGURATIONS)]
#: Priors without lower orders to grow their history through.
RANDOM_WALKS = ("zero-velocity", "constant-velocity")


def test_every_learned_prior_declares_small_models_and_its_parts_options():
    """Each learned prior of the package declares the small models its contract builds it from, and its
    registration declares its parts' options (:func:`priors.learned.part_options`), each part once."""
    from priors.learned import part_options
    from tracker.app.api import prior_entry

    assert set(LEARNED) >= {"crbm", "fcrbm", "deep-crbm", "gpdm", "neural"}
    for name, cls in LEARNED.items():
        assert cls.SMALL_MODELS, f"{name} declares no SMALL_MODELS to build its contract configurations from"
        assert len({s.name for s in cls.PARTS}) == len(cls.PARTS) == len({s.kind for s in cls.PARTS}), name
        declared = [o for o in prior_entry(name).options if o.name in {p.name for p in part_options(cls.PARTS)}]
        assert declared == list(part_options(cls.PARTS)), name


@pytest.mark.slow
def test_every_learned_prior_is_checked_with_every_part_it_takes_switched_on(built):
    """The contract checks each part through the part protocol (:meth:`TestRegisteredPriors.parts`): some
    configuration of each learned prior has every part it declares in use."""
    for name, cls in LEARNED.items():
        expected = sorted(spec.kind.__name__ for spec in cls.PARTS)
        found = [sorted(type(p).__name__ for p in getattr(built(k), "parts", ()))
                 for k, (prior, _, _) in enumerate(CONFIGURATIONS) if prior == name]
        assert expected in found, f"no configuration of {name} uses all of {expected}: {found}"


@pytest.mark.slow
def test_every_learned_prior_names_its_parts_in_use(built):
    """Each learned prior answers :meth:`~priors.learned.LearnedPrior.part` for every part it declares, by name
    and by type alike (the part in use, or None), and uses no part it does not declare."""
    from priors.learned import LearnedPrior

    learned = [built(k) for k in range(len(CONFIGURATIONS)) if isinstance(built(k), LearnedPrior)]
    assert {p.name for p in learned} >= set(LEARNED)
    for prior in learned:
        kinds = {spec.kind for spec in prior.PARTS}
        assert all(type(p) in kinds for p in prior.parts), prior.name
        for spec in prior.PARTS:
            assert prior.part(spec.name) is prior.part(spec.kind), f"{prior.name}.part({spec.name!r})"
        with pytest.raises(KeyError):
            prior.part("no such part")


def test_every_registered_prior_of_the_package_has_a_contract_configuration():
    missing = sorted(set(package_priors()) - set(BUILT))
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
            if options == PARTS_ON:
                options = parts_switched_on(LEARNED[name], paced=models[files[0]][1])
            cache[k] = build_prior(name, _Seq(), [models[f][0] for f in files], step_std=step_std, **options)
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
        from priors.learned import LearnedPrior
        from priors.parts import PostureOffset

        posture = [m.part(PostureOffset) for m in members(prior) if isinstance(m, LearnedPrior)]
        return 0 if any(p is not None for p in posture) else 2

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
