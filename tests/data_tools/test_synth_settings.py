"""The synthetic sequences' settings are declared once (:data:`SYNTH_OPTIONS`): ``SynthConfig``'s fields, the
``synth`` flags and ``tracker.synthesize``'s keywords follow them."""
import dataclasses

import pytest

from data_tools.synthesis.synth_settings import FIELD_OF, SYNTH_OPTIONS, SynthConfig
from tracker.app.parser import build_parser
from tracker.core.errors import InputError


def test_every_option_is_a_field_and_every_field_an_option():
    fields = [f.name for f in dataclasses.fields(SynthConfig)]
    assert fields == [FIELD_OF.get(o.name, o.name) for o in SYNTH_OPTIONS]
    config = SynthConfig()
    assert config.as_options() == {o.name: o.default for o in SYNTH_OPTIONS}


def test_the_synth_command_has_one_flag_per_option_with_its_default():
    args = build_parser(["synth"]).parse_args(["synth", "--mocap", "x.amc", "--out", "o"])
    assert {o.name: getattr(args, o.name) for o in SYNTH_OPTIONS} == {o.name: o.default for o in SYNTH_OPTIONS}


def test_none_takes_the_default_by_name_and_is_refused_as_a_field():
    assert SynthConfig.of({"cameras": None, "noise": None}) == SynthConfig()
    with pytest.raises(InputError, match="cameras must be given"):
        SynthConfig(views=None)
    with pytest.raises(InputError, match=r"unknown synth setting 'colour' \(the settings: cameras, fps, start"):
        SynthConfig.of({"colour": 1})
