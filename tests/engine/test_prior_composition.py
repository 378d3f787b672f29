"""A registry entry answers for its prior: how many model files it takes (one check for the API, experiment files
and the mixture), what it is built from (``resolve``), and, for a prior made of other priors, the files its
options name and how its components are written (the mixture's ``Composition``)."""
from pathlib import Path

import pytest

from tracker.app.plugins import prior_entry
from tracker.core.errors import InputError
from tracker.engine.registry import (
    PRIORS,
    GivenComponent,
    PriorEntry,
    ResolvedPrior,
    register_prior,
)


@pytest.mark.parametrize("kind, count, refusal", [
    ("none", 1, "prior p takes no model files"),
    ("one", 0, "prior p needs models = \\[...\\]"),
    ("several", 0, "prior p needs models = \\[...\\]"),
    ("one", 2, "prior p takes one model file, got 2"),
])
def test_a_wrong_number_of_model_files_is_one_line_naming_the_prior(kind, count, refusal):
    entry = PriorEntry("p", lambda *a: None, model_files=kind)
    with pytest.raises(InputError, match=refusal):
        entry.check_model_files(count, needs="models = [...]")


@pytest.mark.parametrize("kind, count", [("none", 0), ("one", 1), ("several", 3), ("any", 0), ("any", 5)])
def test_the_right_number_of_model_files_passes(kind, count):
    PriorEntry("p", lambda *a: None, model_files=kind).check_model_files(count)


def test_a_plain_prior_resolves_to_its_checked_options_and_given_files():
    entry = prior_entry("zero-velocity")
    resolved = entry.resolve({}, ())
    assert resolved == ResolvedPrior(entry.resolve({}).options, ())
    assert entry.located({"prior_scale": 1.0}, str.upper) == {"prior_scale": 1.0}
    with pytest.raises(InputError, match="prior zero-velocity takes no option 'nope'"):
        entry.resolve({"nope": 1})


def test_the_mixture_resolves_its_default_and_names_its_components_files(tmp_path):
    entry = prior_entry("mixture")
    default = entry.resolve({}, ())
    assert default.options["components"] == "neural,zero-velocity" and len(default.model_files) == 1
    named = entry.resolve({"components": "crbm:model=a.pt,zero-velocity"}, ())
    assert named.named_files == (Path("a.pt"),) and named.model_files == ()
    assert entry.referenced_files(named.options) == [Path("a.pt")]
    assert entry.complete(default.options, default.model_files) == (default.options, list(default.model_files))


def test_the_mixture_locates_the_files_its_components_name():
    entry = prior_entry("mixture")
    options = {"components": "crbm:model=a.pt:gibbs_steps=3,zero-velocity", "switch": 0.1}
    assert entry.located(options, lambda m: f"/abs/{m}") == {
        "components": "crbm:model=/abs/a.pt:gibbs_steps=3,zero-velocity", "switch": 0.1}
    unnamed = {"components": "crbm,zero-velocity"}
    assert entry.located(unnamed, lambda m: f"/abs/{m}") is unnamed


def test_the_mixture_writes_components_given_as_tables():
    composition = prior_entry("mixture").composition
    assert composition.option == "components"
    written = composition.written([GivenComponent("crbm", {"gibbs_steps": 10}, 1),
                                   GivenComponent("zero-velocity", {}, 0),
                                   GivenComponent("crbm", {"label": "a, b"}, 2)])
    assert written == 'crbm:gibbs_steps=10,zero-velocity,crbm:models=2:label="a, b"'
    with pytest.raises(InputError, match=r"component 1 \(crbm\): a component's option must be"):
        composition.written([GivenComponent("crbm", {"gibbs_steps": [1]}, 1)])


def test_the_former_hooks_of_register_prior_still_work_with_a_warning():
    with pytest.warns(DeprecationWarning, match="composition"):
        @register_prior("test-former-hooks", model_files="any", referenced_files=lambda o: ["x.pt"],
                        given_defaults=lambda o, m: ({**o, "given": True}, m or ["default.pt"]))
        def build(context, model_files, options):
            return None
    try:
        entry = prior_entry("test-former-hooks")
        assert entry.resolve({}, ()) == ResolvedPrior({"given": True}, ("default.pt",), (Path("x.pt"),))
        assert entry.complete({}, ["m.pt"]) == ({"given": True}, ["m.pt"])
        assert entry.referenced_files({}) == [Path("x.pt")]
    finally:
        PRIORS.entries.pop("test-former-hooks", None)  # other tests list every registered prior
