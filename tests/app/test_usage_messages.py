"""Usage mistakes a new user makes, answered in one line that says what to do: a mistyped flag names the nearest
flag of the command; the API's ``build_prior`` without a sequence says what it needs."""
from __future__ import annotations

import pytest

from tests.faults.test_bad_input_cli import one_line_refusal, run_cli
from tracker import build_prior
from tracker.core.errors import InputError


@pytest.mark.parametrize("typo, meant", [("--particels", "--particles"), ("--anealing-layers", "--annealing-layers"),
                                         ("--seeed", "--seed")])
def test_a_mistyped_flag_names_the_nearest_flag_of_the_command(typo, meant, capsys, tmp_path):
    code, err = run_cli(["track", str(tmp_path), "--prior", "zero-velocity", typo, "3", "--out",
                         str(tmp_path / "out")], capsys)
    line = one_line_refusal(code, err, "track: unrecognized arguments", typo)
    assert line.endswith(f"(did you mean {meant}?)"), line


def test_a_flag_unlike_any_other_gets_no_suggestion(capsys, tmp_path):
    code, err = run_cli(["track", str(tmp_path), "--prior", "zero-velocity", "--frobnicate", "3"], capsys)
    line = one_line_refusal(code, err, "unrecognized arguments: --frobnicate 3")
    assert "did you mean" not in line


def test_a_flag_of_another_command_is_looked_up_in_the_command_typed(capsys, tmp_path):
    code, err = run_cli(["convert", "--mocap", "x.amc", "--out", "x.npz", "--particels", "5"], capsys)
    line = one_line_refusal(code, err, "convert: unrecognized arguments")
    assert "did you mean" not in line  # convert has no --particles


def test_build_prior_without_a_sequence_says_what_it_needs():
    with pytest.raises(InputError, match=r"needs the sequence the prior will track .*build_prior\('mixture', "
                                         r"sequence, models="):
        build_prior("mixture", models=["crbm.pt"])
