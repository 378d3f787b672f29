"""Command-line conventions: the program's name, one form for every refusal, log lines on stderr (``--quiet``,
``--verbose``) apart from the results on stdout, the number of cameras named ``--cameras`` (``--views`` is
track's list of camera indices), and one ``result.json`` from ``track`` and from ``compare``."""
from __future__ import annotations

import json
import logging
import subprocess
import sys
from datetime import datetime
from pathlib import Path

import pytest

import tracker
from data_tools.samples import sample_walks
from tracker.app import cli
from tracker.app.parser import build_parser
from tracker.core.metrics import METRICS

ASF, WALKS = sample_walks()
AMC = str(WALKS[1])  # 07_02
PACKAGES = ("tracker", "priors", "likelihoods", "data_tools")
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tiny_sequence(tmp_path_factory) -> Path:
    """Five frames of the shipped walk 07_02 in two small cameras (the shipped data: no ../shared needed)."""
    out = tmp_path_factory.mktemp("conventions") / "walk"
    tracker.synthesize(WALKS[1], out, skeleton=ASF, cameras=2, frames=5, width=160, height=120)
    return out


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    """Exit status, stdout and stderr of ``pose-tracker ARGV`` run in this process."""
    capsys.readouterr()
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse's own exits (--help, --version, usage errors)
        code = exc.code
    printed = capsys.readouterr()
    return code, printed.out, printed.err


def refusal(code: int, err: str) -> str:
    """The one line of a refusal: status 2, ``pose-tracker: error: ...``, nothing else on stderr."""
    lines = [s for s in err.splitlines() if s.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("pose-tracker: error: "), (code, err)
    return lines[0]


# -- the program's name ---------------------------------------------------------------------------------------

def test_help_and_usage_name_the_program_pose_tracker():
    parser = build_parser(["track"])
    assert parser.format_usage().startswith("usage: pose-tracker ")
    sub = next(a for a in parser._actions if a.dest == "command").choices
    for name, command in sub.items():
        assert command.format_usage().startswith(f"usage: pose-tracker {name}"), name
        assert "python -m tracker" not in command.format_help(), name
    assert "python -m tracker" not in parser.format_help()


@pytest.mark.slow
def test_python_dash_m_tracker_is_the_same_program(capsys):
    r = subprocess.run([sys.executable, "-m", "tracker", "--version"], capture_output=True, text=True, cwd=REPO)
    assert r.returncode == 0 and r.stdout.strip() == f"pose-tracker {tracker.__version__}"
    r = subprocess.run([sys.executable, "-m", "tracker", "track", "--particles", "x"], capture_output=True,
                       text=True, cwd=REPO)
    assert refusal(r.returncode, r.stderr) == ("pose-tracker: error: track: argument --particles: expected an "
                                               "integer, got 'x'")


# -- refusals ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("argv, line", [
    (["track", "--particles", "x"], "pose-tracker: error: track: argument --particles: expected an integer, got 'x'"),
    (["nope"], "pose-tracker: error: argument COMMAND: invalid choice: 'nope'"),
    (["synth", "--out", "s"], "pose-tracker: error: synth: the following arguments are required: --mocap"),
    (["--quiet", "--verbose", "demo"], "pose-tracker: error: argument -v/--verbose: not allowed with argument "
                                       "-q/--quiet"),
    (["track", "--prior", "zero-velocity"], "pose-tracker: error: track: missing DIR and --out"),
    (["track", "seq", "--out", "o"], "pose-tracker: error: track: missing --prior"),
])
def test_every_refusal_has_one_form_and_names_what_is_missing(argv, line, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(argv, capsys)
    assert refusal(code, err).startswith(line) and out == ""


def test_a_file_that_is_no_model_is_named_with_its_problem_and_leaves_nothing(tiny_sequence, tmp_path, capsys):
    notes = tmp_path / "notes.txt"
    notes.write_text("tracking notes\n")
    out = tmp_path / "run"
    code, _, err = run_cli(["track", str(tiny_sequence), "--prior", "crbm", "--model", str(notes), "--out", str(out)],
                           capsys)
    assert refusal(code, err) == (f"pose-tracker: error: {notes}: not a CRBM model file: it is not a (complete) torch "
                                  "archive, which is what pose-tracker train writes")
    assert not out.exists() or not any(out.iterdir())  # the same command with a good model file is not refused
    other = REPO / "tests" / "data" / "gpdm_v0.13.pt"
    code, _, err = run_cli(["track", str(tiny_sequence), "--prior", "crbm", "--model", str(other), "--out", str(out)],
                           capsys)
    assert refusal(code, err) == (f"pose-tracker: error: {other}: not a CRBM model file: it holds 'pose-tracker gpdm "
                                  "v1', a CRBM model file has format 'pose-tracker crbm v1'")


@pytest.mark.slow
def test_train_reads_its_clips_before_it_announces_the_training(tmp_path, capsys):
    bad = tmp_path / "07_09.amc"
    bad.write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 1 2\n")
    code, out, err = run_cli(["train", "--prior", "gpdm", "--mocap", AMC, str(bad), "--skeleton", str(ASF),
                              "--out", str(tmp_path / "m.pt")], capsys)
    assert str(bad) in refusal(code, err) and "training" not in err and out == ""
    assert not (tmp_path / "m.pt").exists()
    # A setting the prior itself refuses (an FCRBM's labels, one per clip) is refused before the announcement too.
    code, out, err = run_cli(["train", "--prior", "fcrbm", "--mocap", AMC, str(WALKS[0]), "--skeleton", str(ASF),
                              "--labels", "walk", "--out", str(tmp_path / "m.pt")], capsys)
    assert "1 label(s) given for 2 training clip(s)" in refusal(code, err) and "training a" not in err
    code, out, err = run_cli(["train", "--prior", "crbm", "--mocap", AMC, "--skeleton", str(ASF), "--order", "1",
                              "--hidden", "5", "--epochs", "1", "--out", str(tmp_path / "m.pt")], capsys)
    assert code == 0 and f"-> {tmp_path / 'm.pt'}" in out  # how the training went: the result, on stdout
    assert err.startswith("training a crbm prior on 1 clip(s), ") and "Traceback" not in err


# -- log lines and results ------------------------------------------------------------------------------------

def track_argv(sequence: Path, out: Path) -> list[str]:
    return ["track", str(sequence), "--prior", "zero-velocity", "--particles", "30", "--out", str(out)]


def test_results_go_to_stdout_and_the_rest_to_stderr_unless_quiet(tiny_sequence, tmp_path, capsys):
    code, out, err = run_cli(track_argv(tiny_sequence, tmp_path / "a"), capsys)
    assert code == 0 and out.count("\n") == 1
    assert out.startswith("zero-velocity, 3 frames tracked: mpjpe_abs ") and "pck_rel" in out
    assert "s per frame" in err and "tracking (zero-velocity)" in err  # the timing line and the progress bar
    for flags in (["--quiet"], ["-q"]):  # before the command or after it
        for argv in ([*flags, *track_argv(tiny_sequence, tmp_path / "b")],
                     [*track_argv(tiny_sequence, tmp_path / "c"), *flags]):
            code, quiet_out, quiet_err = run_cli([*argv, "--overwrite"], capsys)
            assert code == 0 and quiet_err == "" and quiet_out.split(" -> ")[0] == out.split(" -> ")[0], argv


def test_verbose_shows_debug_lines(capsys):
    code, _, _ = run_cli(["--verbose", "track", "--prior", "zero-velocity"], capsys)
    assert code == 2
    assert logging.getLogger("tracker").isEnabledFor(logging.DEBUG)
    logging.getLogger("tracker.app.cli").debug("a debug line")
    assert capsys.readouterr().err == "tracker.app.cli: a debug line\n"
    run_cli(["track", "--prior", "zero-velocity"], capsys)  # each run sets the level anew
    assert not logging.getLogger("tracker").isEnabledFor(logging.DEBUG)


@pytest.mark.slow
def test_the_packages_never_configure_logging():
    """Library rule: only the command line adds a handler; importing and using the API adds none, and no module
    calls basicConfig."""
    for package in PACKAGES:
        for path in (REPO / package).rglob("*.py"):
            assert "basicConfig" not in path.read_text(), path
    code = ("import logging, tracker.app.api, tracker.app.compare, tracker.app.demo, priors, likelihoods, data_tools\n"
            "import tracker.app.cli\n"
            f"print(sum(len(logging.getLogger(n).handlers) for n in ('', *{PACKAGES!r})))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert r.returncode == 0 and r.stdout.strip() == "0", r.stderr[-500:]


# -- cameras: a count; views: camera indices ------------------------------------------------------------------

@pytest.mark.slow
def test_synth_counts_cameras_and_warns_on_the_old_spelling(tmp_path, capsys):
    base = ["synth", "--mocap", AMC, "--skeleton", str(ASF), "--frames", "2", "--width", "64", "--height", "48"]
    code, _, err = run_cli([*base, "--cameras", "1", "--out", str(tmp_path / "a")], capsys)
    assert code == 0 and "warning" not in err
    assert len(tracker.load_sequence(tmp_path / "a").rig.cameras) == 1
    code, _, err = run_cli([*base, "--views", "3", "--out", str(tmp_path / "b")], capsys)
    warnings = [s for s in err.splitlines() if "warning" in s]
    assert code == 0 and warnings == ["pose-tracker: warning: synth --views is deprecated and will be removed: use "
                                      "--cameras N (a number of cameras; track's --views is a list of camera "
                                      "indices)"]
    assert len(tracker.load_sequence(tmp_path / "b").rig.cameras) == 3


def test_the_api_and_experiment_files_count_cameras_too(tmp_path, caplog):
    from tracker.app.experiment import load_experiment

    with caplog.at_level(logging.WARNING):
        seq = tracker.synthesize(WALKS[1], tmp_path / "s", skeleton=ASF, views=1, frames=2, width=64, height=48)
    assert seq.n_views == 1 and "synthesize: views is deprecated" in caplog.text and "use cameras" in caplog.text
    caplog.clear()
    experiment = tmp_path / "e.toml"
    for key, warned in (("cameras", False), ("views", True)):
        experiment.write_text(f'seeds = 1\n[[sequence]]\nname = "w"\nmocap = "{AMC}"\n{key} = 2\nframes = 4\n'
                              '[[prior]]\nname = "zero-velocity"\n')
        with caplog.at_level(logging.WARNING):
            exp = load_experiment(experiment)
        assert exp.sequences[0].synth["cameras"] == 2 and ("views is deprecated" in caplog.text) == warned
    experiment.write_text(experiment.read_text().replace("views = 2", "views = 2\ncameras = 2"))
    with pytest.raises(tracker.InputError, match="not both cameras and views"):
        load_experiment(experiment)


# -- result.json ------------------------------------------------------------------------------------------------

def test_track_and_compare_write_the_same_result(tiny_sequence, tmp_path, capsys):
    from tracker.app.compare import compare

    assert run_cli([*track_argv(tiny_sequence, tmp_path / "t"), "--frames", "5", "-q"], capsys)[0] == 0
    tracked = json.loads((tmp_path / "t" / "result.json").read_text())
    assert (tracked["frames"], tracked["frames_known"], tracked["frames_tracked"]) == (5, 2, 3)
    assert tracked["version"] == tracker.__version__ and tracked["invocation"]["argv"][:2] == ["pose-tracker", "track"]
    started, finished = (datetime.fromisoformat(tracked[k]) for k in ("started", "finished"))
    assert started.utcoffset().total_seconds() == 0 and started <= finished
    assert list(tracked["metrics"]) == [m.name for m in METRICS]
    for name, m in tracked["metrics"].items():
        assert len(m["per_frame"]) == 3 and m["unit"] == ("%" if name.startswith("pck") else "mm"), name

    experiment = tmp_path / "exp.toml"
    experiment.write_text(f'seeds = 1\n[tracking]\nparticles = 30\n[[sequence]]\nname = "w"\npath = "{tiny_sequence}"\n'
                          '[[prior]]\nname = "zero-velocity"\n')
    compare(experiment, tmp_path / "c", say=lambda s: None, progress=False, videos=False)
    run = json.loads(next((tmp_path / "c" / "runs").glob("*/result.json")).read_text())
    assert set(run) - {"run", "wall_seconds"} == set(tracked)
    assert list(run["metrics"]) == list(tracked["metrics"]) and run["frames_tracked"] == 3
    assert run["invocation"]["function"] == "tracker.track" and run["invocation"]["arguments"]["particles"] == 30
    table = (tmp_path / "c" / "table.csv").read_text()
    assert all(f"\n{m.name}," in table for m in METRICS)


def test_runs_finished_before_the_metrics_were_grouped_are_still_read(tiny_sequence, tmp_path):
    """A run folder whose result.json has the earlier flat keys (``per_frame_error_mm``, ...) is read, not rerun:
    its numbers fill the tables, and a metric it lacks shows as n/a."""
    from tracker.app.compare import compare

    experiment = tmp_path / "exp.toml"
    experiment.write_text(f'seeds = 1\n[tracking]\nparticles = 30\n[[sequence]]\nname = "w"\npath = "{tiny_sequence}"\n'
                          '[[prior]]\nname = "zero-velocity"\n')
    compare(experiment, tmp_path / "c", say=lambda s: None, progress=False, videos=False)
    path = next((tmp_path / "c" / "runs").glob("*/result.json"))
    now = json.loads(path.read_text())
    earlier = {k: v for k, v in now.items() if k != "metrics"}
    earlier.update({"per_frame_error_mm": [e + 100.0 for e in now["metrics"]["mpjpe_abs"]["per_frame"]],
                    "per_frame_relative_error_mm": now["metrics"]["mpjpe_rel"]["per_frame"],
                    "per_frame_pa_mpjpe_mm": now["metrics"]["pa_mpjpe"]["per_frame"],
                    "per_frame_pck150": now["metrics"]["pck_abs"]["per_frame"]})
    path.write_text(json.dumps(earlier))
    said: list[str] = []
    compare(experiment, tmp_path / "c", say=said.append, progress=False, videos=False)
    assert any("1 finished before (skipped), 0 to run" in s for s in said)
    rows = {r.split(",")[0]: r for r in (tmp_path / "c" / "table.csv").read_text().splitlines()[1:]}
    mean = float(rows["mpjpe_abs"].split(",")[3])
    assert mean == pytest.approx(now["metrics"]["mpjpe_abs"]["mean"] + 100.0, abs=1e-3)
    assert "pck_rel" not in rows and "| zero-velocity | n/a |" in (tmp_path / "c" / "table.md").read_text()
