"""The part protocol (:class:`priors.parts.Part`): every part declares its options once, checks their bounds from
those declarations, reports its settings under their names, starts exactly the state it owns, and a learned
prior's settings use its options' names."""
from pathlib import Path

import numpy as np
import pytest

from priors.parts import GroundDiffusion, HeightOffset, PaceInput, Part, PostureOffset, Step
from tracker.core.errors import InputError

PARTS = (GroundDiffusion, PaceInput, HeightOffset, PostureOffset)
DATA = Path(__file__).parents[1] / "data"


@pytest.mark.parametrize("kind", PARTS)
def test_a_part_declares_one_option_per_field_and_reports_settings_under_their_names(kind):
    part = kind()
    assert isinstance(part, Part)
    assert list(part.settings()) == [o.name for o in kind.OPTIONS]
    assert part.settings() == {o.name: o.default for o in kind.OPTIONS}  # the fields' defaults are the options'
    assert len(kind.UNITS) == len(kind.OPTIONS)


@pytest.mark.parametrize("kind", PARTS)
def test_a_part_refuses_values_outside_its_options_bounds(kind):
    for i, option in enumerate(kind.OPTIONS):
        values = [o.default for o in kind.OPTIONS]
        kind(*values[:i], option.maximum, *values[i + 1:])  # the bounds themselves are allowed
        for bad in (option.minimum - 1e-9, option.maximum * 1.01 + 1e-9, float("nan"), True, "1"):
            with pytest.raises(InputError, match=option.name.replace("_", " ")):
                kind(*values[:i], bad, *values[i + 1:])


@pytest.mark.parametrize("part", [PaceInput(), HeightOffset(30.0, 2.0), PostureOffset(0.2), GroundDiffusion()],
                         ids=lambda p: type(p).__name__)
def test_a_part_starts_exactly_the_state_it_owns_one_row_per_particle(part, walk_07_01):
    state = part.start(walk_07_01.poses[:3], 7, np.random.default_rng(0))
    assert set(state) == set(part.KEYS)
    assert all(np.asarray(v).shape[0] == 7 for v in state.values())
    assert set(part.restart(state, state, 7)) == set(part.KEYS)


def test_a_part_with_nothing_to_draw_draws_nothing():
    rng = np.random.default_rng(3)
    before = rng.bit_generator.state
    for part in (GroundDiffusion(0.0), PaceInput(0.3, 0.0), HeightOffset(30.0, 0.0), PostureOffset(0.5)):
        assert part.noise(5, rng) is None
    assert rng.bit_generator.state == before


def test_the_height_offset_moves_history_and_draw_in_opposite_directions():
    part = HeightOffset(10.0, 2.0)
    history, drawn = np.zeros((3, 2, 8)), np.zeros((3, 8))
    step = Step(previous=np.zeros((3, 8)), history=history, model=None)
    part.condition({"height_offset": np.array([1.0, 2.0, 3.0])}, step, np.array([0.0, 0.5, -0.5]))
    assert np.array_equal(step.new["height_offset"], [1.0, 3.0, 2.0])
    assert np.array_equal(history[:, :, 2], -np.array([[1.0, 1.0], [3.0, 3.0], [2.0, 2.0]]))
    step.drawn = drawn
    part.propose({}, step, None)
    assert np.array_equal(drawn[:, 2], [1.0, 3.0, 2.0]) and not drawn[:, [0, 1, 3]].any()


@pytest.mark.parametrize("name, model, options", [
    ("crbm", "crbm3_paced_v0.13.pt", {"height_drift": 1.0}),
    ("gpdm", "gpdm_v0.13.pt", {"posture_gain": 0.1}),
])
def test_a_learned_priors_settings_use_its_option_names(name, model, options, walk_07_01):
    from tracker.app.api import build_prior, prior_entry

    class Sequence:  # what build_prior reads of a sequence
        model = walk_07_01.model
        fps = 60.0
        root = Path("parts")

    prior = build_prior(name, Sequence(), [DATA / model], **options)
    settings = prior.settings()
    declared = {o.name for o in prior_entry(name).options}
    assert declared <= set(settings), declared - set(settings)
    for key, value in options.items():
        assert settings[key] == value


def test_a_learned_priors_parts_come_in_the_order_it_declares_them():
    """One function turns a prior's declared parts into its parts (:func:`priors.learned.resolve_parts`): in the
    declared order (the order of the step's random draws), a given part before the options, the options before the
    defaults, the pace part exactly for a model with a pace input."""
    from priors.learned import PartSpec, resolve_parts

    ground, height, posture = (PartSpec("ground", GroundDiffusion), PartSpec("height", HeightOffset),
                               PartSpec("posture", PostureOffset))
    pace = PartSpec("pace", PaceInput, paced=True)
    assert [type(p) for p in resolve_parts((ground, height, posture))] == [GroundDiffusion, HeightOffset, PostureOffset]
    assert [type(p) for p in resolve_parts((pace, height, posture, ground), paced=True)] == \
        [PaceInput, HeightOffset, PostureOffset, GroundDiffusion]
    assert [type(p) for p in resolve_parts((pace, height, posture, ground))] == \
        [HeightOffset, PostureOffset, GroundDiffusion]
    parts = resolve_parts((ground, height), options={"root_noise": 2.0, "height_spread": None, "height_drift": 1.0},
                          given={"height": HeightOffset(7.0)})
    assert parts == (GroundDiffusion(2.0), HeightOffset(7.0))
    assert resolve_parts((height,), options={"height_spread": None}) == (HeightOffset(),)


def test_a_learned_priors_declared_defaults_and_refusals():
    from priors.learned import PACED_DEFAULT, PartSpec, part_options, resolve_parts

    height = PartSpec("height", HeightOffset, paced_defaults={"height_spread": 50.0})
    assert resolve_parts((height,), paced=False) == (HeightOffset(0.0),)
    with pytest.raises(InputError, match="takes no pace input"):
        resolve_parts((height,), paced=True, kind="CRBM")
    assert resolve_parts((pace_spec := PartSpec("pace", PaceInput, paced=True), height), paced=True) == \
        (PaceInput(), HeightOffset(50.0))
    tall = PartSpec("height", HeightOffset, defaults={"height_spread": 40.0})
    assert resolve_parts((tall,)) == (HeightOffset(40.0),)
    options = {o.name: o for o in part_options((PartSpec("posture", PostureOffset), tall))}
    assert options["height_spread"].default == 40.0
    pace = pace_spec
    assert [o.name for o in part_options((PartSpec("posture", PostureOffset), height, pace,
                                          PartSpec("ground", GroundDiffusion)))] == \
        ["root_noise", "pace_spread", "pace_drift", "height_spread", "height_drift", "posture_gain"]
    assert part_options((height,))[0].default is None
    assert part_options((height,))[0].default_note == PACED_DEFAULT.format(paced=50.0)
    with pytest.raises(InputError, match="pace spread applies to a model trained with a pace input"):
        resolve_parts((pace, height), options={"pace_spread": 0.2}, kind="CRBM")
    with pytest.raises(InputError, match="pace settings are for a CRBM trained with a pace input"):
        resolve_parts((pace, height), given={"pace": PaceInput()}, kind="CRBM")
    with pytest.raises(TypeError, match="takes the parts height"):
        resolve_parts((height,), given={"posture": PostureOffset(0.1)})
    with pytest.raises(TypeError, match="HeightOffset"):
        resolve_parts((height,), given={"height": PostureOffset(0.1)})
