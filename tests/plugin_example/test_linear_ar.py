"""The extension guide's learned prior (docs/guide/extending.md, "Add a learned prior"), run: the package
:mod:`.linear_ar` imported as a plugin is (by its module's name, as ``pose-tracker --plugin MODULE`` and a
``pose_tracker.plugins`` entry point import it), checked by the shipped prior contract at its defaults and with
every part it declares switched on, trained with ``tracker.train`` on the shipped walk 07_01 and tracking with
``tracker.track``; and the guide's code is the package's prior module, word for word. No shared data needed."""
from __future__ import annotations

import importlib
import re
from pathlib import Path
from types import ModuleType
from typing import Any, Iterator

import numpy as np
import pytest

import tracker
from data_tools.samples import sample_walks
from tracker.testing import PriorContract

#: The module that registers the prior: what the plugin's entry point or ``--plugin`` names.
PLUGIN = f"{__package__}.linear_ar.prior"
PRIOR_FILE = Path(__file__).with_name("linear_ar") / "prior.py"
GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "extending.md"


@pytest.fixture(scope="module")
def plugin() -> Iterator[ModuleType]:
    """The plugin's prior module, imported by name through the toolkit's plugin loader; its prior is taken out
    of the registry after this module's tests."""
    from tracker.app.plugins import import_plugin
    from tracker.engine.registry import PRIORS

    import_plugin(PLUGIN)
    yield importlib.import_module(PLUGIN)
    PRIORS.entries.pop("linear-ar", None)


@pytest.fixture(scope="module")
def walk() -> Any:
    """The shipped walk 07_01 retargeted to the 15-cone model at 60 Hz (poses ``T x 40``, mm and radians)."""
    asf, amcs = sample_walks()
    return tracker.load_clip(amcs[0], skeleton=asf)


@pytest.fixture(scope="module")
def trained(plugin: ModuleType, tmp_path_factory) -> tuple[Any, Path]:
    """The small model the prior declares, trained through ``tracker.train`` on 07_01, and its model file."""
    asf, amcs = sample_walks()
    small = plugin.LinearARPrior.SMALL_MODELS[0]
    model = tracker.train("linear-ar", amcs[:small.clips], skeletons=[asf] * small.clips, seed=0, **small.options)
    path = tmp_path_factory.mktemp("linear_ar") / "linear_ar.pt"
    model.save(path)
    return model, path


def every_part_on(plugin: ModuleType) -> dict[str, float]:
    """Option values that switch on every part the prior declares: an option's default where that is on, else a
    hundredth of its maximum."""
    return {o.name: o.default or o.maximum / 100 for spec in plugin.LinearARPrior.PARTS for o in spec.options()}


class TestLinearAR(PriorContract):
    """The contract on the prior built from its model file through the registry, at its defaults."""

    every_part = False

    @pytest.fixture(autouse=True)
    def built(self, plugin, trained, walk):
        class _Sequence:  # what build_prior reads of a sequence
            model, fps, root = walk.model, 60.0, Path("linear-ar")

        options = every_part_on(plugin) if self.every_part else {}
        self.prior = tracker.build_prior("linear-ar", _Sequence(), [trained[1]], **options)
        self.poses = walk.poses[:8]

    def make_prior(self):
        return self.prior

    def known_poses(self):
        return self.poses

    def parts(self, prior):
        return list(prior.parts)

    def frames_before_batch_check(self, prior):
        return 0 if prior.part("posture") is not None else 2  # the posture offset sees the whole particle set


class TestLinearARWithEveryPart(TestLinearAR):
    """The contract with every part the prior declares in use."""

    every_part = True

    def test_every_declared_part_is_in_use(self, plugin):
        declared = sorted(spec.kind.__name__ for spec in plugin.LinearARPrior.PARTS)
        assert sorted(type(p).__name__ for p in self.prior.parts) == declared


def test_trained_with_tracker_train_it_tracks_with_tracker_track(trained, small_walk):
    """The model trained on 07_01 tracks five frames of 07_02 in two cameras, the same from the model as from its
    file, within a few centimetres of the truth."""
    model, path = trained
    assert model.summary()
    runs = [tracker.track(small_walk, "linear-ar", models=[m], particles=50, seed=0) for m in (model, path)]
    assert runs[0].settings["prior"] == "linear-ar"
    assert np.array_equal(runs[0].poses, runs[1].poses)
    assert np.all(np.isfinite(runs[0].errors)) and runs[0].mean_error < 80.0, runs[0].errors


def test_the_guides_learned_prior_is_this_plugins_prior_module():
    """The guide's worked example is the file above, character for character (its first line names the file)."""
    blocks = re.findall(r"```python\n(.*?)```", GUIDE.read_text(), re.S)
    assert PRIOR_FILE.read_text() in blocks, f"the guide's learned-prior example differs from {PRIOR_FILE.name}"
