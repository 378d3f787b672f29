"""The schema of a run's settings: every setting is declared once, and the command line, the API, experiment files
and result.json agree with the declaration on its name and default."""
import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

import tracker
from tracker.app.experiment import RunSpec, load_experiment
from tracker.app.parser import build_parser
from tracker.app.schema import EXPERIMENT_SETTINGS, GRID_AXES, RECORDED_SETTINGS, TRACK_SETTINGS, defaults
from tracker.core.errors import InputError
from tracker.engine.config import ENGINE_ANNEALING_LAYERS, FILTER_OPTIONS, FilterConfig
from tracker.engine.registry import Option

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "data_tools" / "samples" / "cmu07"
#: Settings of a run that an experiment file does not take: its runs draw their seeds from the file's own seed,
#: run on the CPU and keep no checkpoints.
NOT_IN_EXPERIMENTS = {"seed", "device", "checkpoint_every"}


def track_parser() -> argparse.ArgumentParser:
    parser = build_parser(["track"])
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices["track"]


def test_the_command_line_has_one_flag_per_setting_with_the_declared_default_and_help():
    actions = {a.dest: a for a in track_parser()._actions}
    for name, option in TRACK_SETTINGS.items():
        action = actions[name]
        assert action.option_strings == [option.flag], name
        assert action.default == option.default, name
        assert action.help == option.described() and option.help in action.help, name


def test_the_api_takes_every_setting_by_name_and_records_its_default(small_walk, tmp_path):
    run = tracker.track(small_walk, "zero-velocity", particles=30)  # every other setting left to its default
    saved = run.save(tmp_path / "out")
    written = json.loads((tmp_path / "out" / "result.json").read_text())
    assert saved == written
    resolved = {"views": [0, 1], "frames": 5, "particles": 30}  # views: all cameras; frames: the whole sequence
    for name in RECORDED_SETTINGS:
        assert written[name] == resolved.get(name, TRACK_SETTINGS[name].default), name
    assert "checkpoint_every" not in written  # checkpoints do not change a run's numbers
    given = tracker.track(small_walk, "zero-velocity", particles=30, annealing_layers=1, survival_rate=0.3,
                          ess_threshold=0.9, layer_diffusion_decay=1.0, known_frames=3, views=[1], seed=4)
    assert {k: given.settings[k] for k in ("annealing_layers", "survival_rate", "ess_threshold",
                                           "layer_diffusion_decay", "known_frames", "views", "seed")} == \
        {"annealing_layers": 1, "survival_rate": 0.3, "ess_threshold": 0.9, "layer_diffusion_decay": 1.0,
         "known_frames": 3, "views": [1], "seed": 4}


def test_the_api_checks_every_setting_by_its_declaration(small_walk):
    for name, bad, rule in [("particles", 0, "at least 1 and at most 1000000"),
                            ("particles", 1_000_001, "at least 1 and at most 1000000"),
                            ("annealing_layers", 2.5, "must be an integer"),
                            ("survival_rate", 1.0, "greater than 0 and less than 1"),
                            ("resampling", "best", "must be one of systematic"),
                            ("known_frames", True, "must be an integer"),
                            ("views", [0, "a"], "must be an integer")]:
        with pytest.raises(InputError, match=rule):
            tracker.track(small_walk, "zero-velocity", **{name: bad})


def test_an_experiment_file_takes_the_settings_with_the_declared_defaults(tmp_path):
    assert set(EXPERIMENT_SETTINGS) == set(TRACK_SETTINGS) - NOT_IN_EXPERIMENTS
    path = tmp_path / "exp.toml"
    path.write_text(f'[[sequence]]\nname = "walk"\nmocap = "{SAMPLE / "07_02.amc"}"\n\n'
                    '[[prior]]\nname = "zero-velocity"\n')
    grid = load_experiment(path).tracking
    for name in EXPERIMENT_SETTINGS:
        default = TRACK_SETTINGS[name].default
        assert grid[name] == ([default] if name in GRID_AXES else default), name
    # a run's settings are the keywords of tracker.track, by the same names
    run = RunSpec("k", "walk", "", "zero-velocity", "zero-velocity", {}, (), None, "edge-silhouette", {},
                  None, 10, 3, None, 2, "systematic", 0, 0, "", filter_options={"survival_rate": 0.5,
                                                                                 "ess_threshold": 0.5,
                                                                                 "layer_diffusion_decay": 0.5})
    assert set(run.settings()) == set(EXPERIMENT_SETTINGS)


@pytest.mark.parametrize("line, message", [
    ("particles = 0", "[tracking] particles must be at least 1 and at most 1000000, got 0"),
    ("particles = [100, true]", "[tracking] particles must be an integer, got True"),
    ("annealing_layers = []", "[tracking] annealing_layers: expected a value or a non-empty list, got []"),
    ("survival_rate = 1.5", "[tracking] survival_rate must be greater than 0 and less than 1"),
    ('resampling = "best"', "[tracking] resampling must be one of systematic"),
    ("known_frames = 0", "[tracking] known_frames must be at least 1, got 0"),
    ("views = [0, -1]", "[tracking] views must be at least 0, got -1"),
    ("views = [0, 0]", "[tracking] views: each view set must list distinct camera indices"),
    ("seed = 3", "[tracking]: unknown key(s) 'seed'"),
])
def test_an_experiment_setting_is_refused_in_one_line_naming_the_file_the_key_and_the_rule(tmp_path, line,
                                                                                           message):
    path = tmp_path / "exp.toml"
    path.write_text(f'[tracking]\n{line}\n\n[[sequence]]\nname = "walk"\nmocap = "{SAMPLE / "07_02.amc"}"\n\n'
                    '[[prior]]\nname = "zero-velocity"\n')
    with pytest.raises(InputError) as err:
        load_experiment(path)
    assert str(err.value).startswith(f"{path}: {message}") and "\n" not in str(err.value)


def test_the_filter_configuration_derives_from_the_declared_options():
    engine = FilterConfig()
    for option in FILTER_OPTIONS:
        value = engine.options()[option.name]
        assert value == (ENGINE_ANNEALING_LAYERS if option.name == "annealing_layers" else option.default)
    assert FilterConfig.from_options({}).options() == defaults([o.name for o in FILTER_OPTIONS])
    with pytest.raises(InputError, match="particles must be at least 1"):
        FilterConfig(n_particles=0).check()
    with pytest.raises(InputError, match="has no setting 'particle'"):
        FilterConfig.from_options({"particle": 3})


def test_an_option_states_its_unit_and_refuses_a_truth_value_for_a_number():
    option = Option("checkpoint_every", int, 25, "save every K frames", minimum=0, unit="frames")
    assert option.described() == "save every K frames (default 25 frames)"
    with pytest.raises(InputError, match="must be an integer, got True"):
        option.parse(True, "track")
    views = Option("views", int, None, "cameras", minimum=0, many=True)
    assert views.parse("0, 2", "track") == (0, 2) and views.parse(range(2), "track") == (0, 1)


def test_a_bad_setting_on_the_command_line_is_one_line_with_the_rule(tmp_path):
    r = subprocess.run([sys.executable, "-m", "tracker", "track", str(tmp_path), "--prior", "zero-velocity",
                        "--survival-rate", "1", "--out", str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.strip() == ("pose-tracker: error: track: argument --survival-rate: must "
                                                      "be greater than 0 and less than 1, got 1.0")


@pytest.mark.parametrize("prior, flag, value, rule", [
    ("mixture", "--switch", "0.9", "must be at least 0 and at most 0.5, got '0.9'"),
    ("mixture", "--switch", "x", "must be a number, got 'x'"),
    ("crbm", "--gibbs-steps", "0", "must be at least 1 and at most 10000, got '0'"),
])
def test_a_bad_plugin_option_on_the_command_line_names_its_flag_once(tmp_path, prior, flag, value, rule):
    r = subprocess.run([sys.executable, "-m", "tracker", "track", str(tmp_path), "--prior", prior, flag, value,
                        "--out", str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.strip() == f"pose-tracker: error: track: argument {flag}: {rule}"

@pytest.mark.parametrize("line, message", [
    ("seeds = 0", "seeds must be at least 1, got 0"),
    ("seed = -2", "seed must be at least 0, got -2"),
    ("fps = 2000", "fps must be at least 1 and at most 1000, got 2000"),
    ('paired = "some"', "paired must be one of baseline, all, got 'some'"),
    ("description = 3", "description must be text, got 3"),
])
def test_the_experiments_own_settings_are_checked_by_their_declarations(tmp_path, line, message):
    path = tmp_path / "exp.toml"
    path.write_text(f'{line}\n[[sequence]]\nname = "walk"\nmocap = "{SAMPLE / "07_02.amc"}"\n\n'
                    '[[prior]]\nname = "zero-velocity"\n')
    with pytest.raises(InputError) as err:
        load_experiment(path)
    assert str(err.value) == f"{path}: {message}"
