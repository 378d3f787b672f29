"""A mixture's components as full citizens: each with its own prior, model and options, on the command line
(``crbm:model=crbm1.pt:gibbs_steps=10,zero-velocity``) and in experiment files (``[[prior.components]]`` tables,
a learned component trained by the experiment and cached like any trained model)."""
import json
from pathlib import Path

import numpy as np
import pytest

import tracker
from priors.mixture_components import Component, parse_components
from tracker.app.compare import compare
from tracker.app.experiment import load_experiment
from tracker.core.errors import InputError

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "data_tools" / "samples" / "cmu07"


@pytest.fixture(scope="module")
def crbm_file(tmp_path_factory) -> Path:
    model = tracker.train("crbm", [SAMPLE / "07_01.amc"], skeletons=[SAMPLE / "07.asf"], order=1, hidden=8,
                          epochs=1, seed=0, pace_input=False)
    path = tmp_path_factory.mktemp("model") / "crbm1.pt"
    model.save(path)
    return path


def test_the_compact_form_is_read_and_written_back():
    written = 'crbm:model=a.pt:model=b.pt:gibbs_steps=10,fcrbm:models=2:style="walk,run@120",zero-velocity'
    components = parse_components(written, "prior mixture")
    assert components == [Component("crbm", ("a.pt", "b.pt"), None, (("gibbs_steps", "10"),)),
                          Component("fcrbm", (), 2, (("style", "walk,run@120"),)),
                          Component("zero-velocity")]
    assert ",".join(c.written() for c in components) == written
    assert parse_components("crbm,zero-velocity", "p") == [Component("crbm"), Component("zero-velocity")]


@pytest.mark.parametrize("components, message", [
    ("zero-velocity", "components must name two or more priors"),
    ("crbm:gibbs_steps,zero-velocity", "give each setting of a component as key=value"),
    ("crbm:models=x,zero-velocity", "models=N, a number of the mixture's model files"),
    ("crbm:model=,zero-velocity", "components name a file in model=FILE (component 1)"),
    ('crbm:model="",zero-velocity', "components name a file in model=FILE (component 1)"),
    ('crbm:mode="a,zero-velocity', "a double quote is not closed"),
    ("crbm:nonsense=3,zero-velocity", "component 1 (crbm) takes no option 'nonsense'"),
    ("crbm:gibbs_steps=0,zero-velocity", "component 1 (crbm): gibbs_steps must be at least 1"),
    ("crbm,zero-velocity:model=a.pt", "component 2 (zero-velocity) takes no model files"),
    ("crbm,mixture", "a mixture cannot be a component of a mixture"),
    ("crbm,nonsense", "unknown prior 'nonsense'"),
])
def test_a_bad_component_is_refused_in_one_line(small_walk, components, message):
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")) as err:
        tracker.track(small_walk, "mixture", components=components, particles=20)
    assert "\n" not in str(err.value)


def test_each_component_is_built_with_its_own_model_and_options(small_walk, crbm_file):
    named = tracker.track(small_walk, "mixture", components=f"crbm:model={crbm_file}:gibbs_steps=3,zero-velocity",
                          particles=40, seed=2, annealing_layers=1)
    settings = named.settings["prior_settings"]["component_settings"]
    assert settings["crbm"]["gibbs_steps"] == 3
    assert named.settings["prior_models"] == [str(crbm_file)]  # in the checkpoint's fingerprint of inputs
    # the same mixture with the model file given the old way, and the option written in the component
    listed = tracker.track(small_walk, "mixture", models=[crbm_file], components="crbm:gibbs_steps=3,zero-velocity",
                           particles=40, seed=2, annealing_layers=1)
    assert np.array_equal(named.poses, listed.poses)
    # the old form: every component at its default options
    default = tracker.track(small_walk, "mixture", models=[crbm_file], particles=40, seed=2, annealing_layers=1)
    assert default.settings["prior_settings"]["component_settings"]["crbm"]["gibbs_steps"] != 3
    assert not np.array_equal(default.poses, listed.poses)


def test_the_command_line_takes_the_compact_form(small_walk, crbm_file, tmp_path):
    from tracker.app.cli import main

    out = tmp_path / "run"
    code = main(["track", str(small_walk), "--prior", "mixture", "--components",
                 f"crbm:model={crbm_file}:gibbs_steps=3,zero-velocity", "--particles", "30", "--out", str(out),
                 "--quiet"])
    result = json.loads((out / "result.json").read_text())
    assert code == 0 and result["prior_options"]["components"].startswith("crbm:model=")
    assert result["prior_settings"]["component_settings"]["crbm"]["gibbs_steps"] == 3


def write_experiment(folder: Path, prior: str) -> Path:
    path = folder / "exp.toml"
    path.write_text(f'''description = "a mixture with a CRBM trained inline"
seed = 3
[tracking]
particles = 30
frames = 4
annealing_layers = 1

[[sequence]]
name = "walk"
mocap = "{SAMPLE / '07_02.amc'}"
frames = 5
cameras = 2
width = 160
height = 120

[[prior]]
name = "zero-velocity"
{prior}''')
    return path


MIXTURE = f'''
[[prior]]
label = "CRBM + zero-velocity"
name = "mixture"
options = {{ switch = 0.1 }}

[[prior.components]]
prior = "crbm"
train = {{ mocap = ["{SAMPLE / '07_01.amc'}"], options = {{ order = 1, hidden = 8, epochs = 1, pace_input = false }} }}
options = {{ gibbs_steps = 3 }}

[[prior.components]]
prior = "zero-velocity"
'''


@pytest.mark.slow
def test_an_experiment_mixes_a_crbm_trained_inline_with_zero_velocity(tmp_path):
    path = write_experiment(tmp_path, MIXTURE)
    said: list[str] = []
    compare(path, tmp_path / "out", say=said.append, progress=False)
    assert sum(s.startswith("training crbm for 'CRBM + zero-velocity'") for s in said) == 1
    runs = [json.loads((d / "result.json").read_text()) for d in (tmp_path / "out" / "runs").iterdir()]
    mixture = next(r for r in runs if r["prior"] == "mixture")
    assert mixture["prior_options"] == {"components": "crbm:gibbs_steps=3,zero-velocity", "switch": 0.1,
                                        "evidence_temperature": 10.0}
    assert mixture["prior_settings"]["component_settings"]["crbm"]["gibbs_steps"] == 3
    assert np.isfinite(mixture["metrics"]["mpjpe_abs"]["mean"])
    again: list[str] = []
    compare(path, tmp_path / "out", say=again.append, progress=False)  # the trained model and the runs cached
    assert not any(s.startswith("training") for s in again)


def test_a_component_given_a_model_file_in_an_experiment(tmp_path, crbm_file):
    tables = f'''
[[prior]]
label = "mixture"
name = "mixture"
[[prior.components]]
prior = "zero-velocity"
[[prior.components]]
prior = "crbm"
models = ["{crbm_file}"]
'''
    prior = load_experiment(write_experiment(tmp_path, tables)).priors[1]
    assert prior.options["components"] == "zero-velocity,crbm" and prior.model_sources() == (crbm_file,)
    one = load_experiment(write_experiment(tmp_path, tables.replace(f'models = ["{crbm_file}"]',
                                                                    f'model = "{crbm_file}"'))).priors[1]
    assert one.options["components"] == "zero-velocity,crbm" and one.model_sources() == (crbm_file,)


@pytest.mark.parametrize("tables, message", [
    ('\n[[prior]]\nname = "mixture"\n[[prior.components]]\nprior = "crbm"\n[[prior.components]]\n'
     'prior = "zero-velocity"\n', "component 1 (crbm): prior crbm needs models = [...] or train = ..."),
    (f'\n[[prior]]\nname = "mixture"\n[[prior.components]]\nprior = "zero-velocity"\n'
     f'train = {{ mocap = ["{SAMPLE / "07_01.amc"}"] }}\n[[prior.components]]\nprior = "constant-velocity"\n',
     "prior zero-velocity is not learned: it has nothing to train"),
    ('\n[[prior]]\nname = "mixture"\n[[prior.components]]\nprior = "zero-velocity"\noptions = { nope = 1 }\n'
     '[[prior.components]]\nprior = "constant-velocity"\n', "component 1: prior zero-velocity takes no option"),
    ('\n[[prior]]\nname = "mixture"\n[[prior.components]]\nprior = "zero-velocity"\n',
     "[[prior.components]] must give two or more components"),
    ('\n[[prior]]\nname = "constant-velocity"\n[[prior.components]]\nprior = "zero-velocity"\n'
     '[[prior.components]]\nprior = "zero-velocity"\n', "prior constant-velocity has no components"),
    ('\n[[prior]]\nname = "mixture"\noptions = { components = "crbm,zero-velocity" }\n[[prior.components]]\n'
     'prior = "zero-velocity"\n[[prior.components]]\nprior = "constant-velocity"\n',
     "either as options.components or as [[prior.components]] tables"),
    ('\n[[prior]]\nname = "mixture"\n[[prior.components]]\nprior = "zero-velocity"\nmodel = "x.pt"\n'
     'models = ["x.pt"]\n[[prior.components]]\nprior = "constant-velocity"\n', "give model = FILE or models = "
     "[FILE, ...], not both"),
    ('\n[[prior]]\nname = "mixture"\n[[prior.components]]\nprior = "zero-velocity"\nmodel = ["x.pt"]\n'
     '[[prior.components]]\nprior = "constant-velocity"\n', "expected a path, got ['x.pt']"),
    ('\n[[prior]]\nname = "mixture"\ncomponents = 5\n', "components are given as [[prior.components]] tables "
     "(each with prior = NAME) or as text, options = { components = \"crbm,zero-velocity\" }; got 5"),
    ('\n[[prior]]\nname = "mixture"\ncomponents = [1, 2]\n', "as [[prior.components]] tables (each with prior = "
     "NAME) or as text, options = { components = \"crbm,zero-velocity\" }; got [1, 2]"),
    ('\n[[prior]]\nname = "mixture"\ncomponents = "crbm,zero-velocity"\n', "or as text, options = { components"),
])
def test_a_bad_component_table_is_refused_in_one_line_naming_the_file(tmp_path, tables, message):
    path = write_experiment(tmp_path, tables)
    with pytest.raises(InputError) as err:
        load_experiment(path)
    assert message in str(err.value) and str(err.value).startswith(str(path)) and "\n" not in str(err.value)


def test_the_shipped_example_of_a_mixture_trained_inline_is_valid():
    exp = load_experiment(REPO / "examples" / "mixture_trained_inline.toml")
    mixture = next(p for p in exp.priors if p.name == "mixture")
    assert mixture.options["components"] == "crbm:gibbs_steps=10,zero-velocity"
    assert [t.prior for t in mixture.train] == ["crbm"]


def test_a_model_file_in_the_components_text_of_an_experiment_is_relative_to_the_file(tmp_path, crbm_file,
                                                                                      monkeypatch):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "c.pt").write_bytes(crbm_file.read_bytes())
    monkeypatch.chdir(crbm_file.parent)  # a crbm1.pt here, and no sub/
    text = '\n[[prior]]\nname = "mixture"\noptions = { components = "crbm:model=sub/c.pt,zero-velocity" }\n'
    prior = load_experiment(write_experiment(tmp_path, text)).priors[1]
    assert prior.options["components"] == f'crbm:model={tmp_path / "sub" / "c.pt"},zero-velocity'
    missing = write_experiment(tmp_path, text.replace("sub/c.pt", "crbm1.pt"))
    with pytest.raises(InputError) as err:  # checked as the file is read, relative to it
        load_experiment(missing)
    assert str(err.value).startswith(str(missing)) and "crbm1.pt" in str(err.value), err.value


def test_each_component_records_its_options_under_their_names(small_walk):
    from tracker.app.plugins import prior_entry

    run = tracker.track(small_walk, "mixture", particles=20, annealing_layers=1,
                        components="zero-velocity:prior_scale=2,constant-velocity:isotropic_ground=true")
    settings = run.settings["prior_settings"]["component_settings"]
    for name in ("zero-velocity", "constant-velocity"):
        assert set(settings[name]) == {o.name for o in prior_entry(name).options}, settings
    assert settings["zero-velocity"] == {"prior_scale": 2.0, "isotropic_ground": False}
    assert settings["constant-velocity"] == {"prior_scale": 1.0, "isotropic_ground": True}
