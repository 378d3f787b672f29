"""The rough edges a new user meets: what result.json, the plots, the report and the messages say, and what the
Python API and the README show."""
from __future__ import annotations

import colorsys
import dataclasses
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import tracker
from data_tools.samples import sample_walks
from tests.faults.test_bad_input_readers import tiny_sequence
from tests.faults.test_faults_disk import run_cli
from tracker.app import cli, console
from tracker.core.errors import InputError

ASF, WALKS = sample_walks()
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def quick_scale(monkeypatch):
    """The random-walk scale, fixed (the default retargets the shipped walks, seconds a run)."""
    import tracker.app.api as api

    monkeypatch.setattr(api, "random_walk_scale", lambda seq, train_mocap=None: np.full(seq.model.n_dofs, 0.02))


def test_a_finished_run_says_it_is_complete(tmp_path, quick_scale):
    seq = tiny_sequence(tmp_path / "seq", frames=5)
    result = tracker.track(seq, "zero-velocity", particles=10, annealing_layers=1).save(tmp_path / "out")
    assert result["complete"] is True and result["frames_tracked"] == 3


def test_pa_mpjpe_aligns_by_least_squares_so_one_lost_limb_can_make_it_exceed_the_absolute_error():
    from tracker.core.metrics import marker_error, procrustes_aligned_error

    rng = np.random.default_rng(0)
    truth = rng.normal(0, 300, (15, 3))
    estimate = truth.copy()
    estimate[7] += [900.0, 0, 0]  # one wrist far off, every other marker exact
    assert procrustes_aligned_error(estimate, truth) > marker_error(estimate, truth)
    page = " ".join((REPO / "docs" / "reference" / "metrics.md").read_text().split())
    assert "squared" in page and "Why PA-MPJPE can exceed the absolute error" in page
    assert "half the particles by construction" in page  # what mean_effective_sample_size means under annealing


def test_the_per_frame_plot_keeps_its_y_label_inside_the_figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from tracker.app.report import PRIMARY, per_frame_figure

    run = {"metrics": {PRIMARY: {"per_frame": [30.0, 32.0, 31.0]}}, "tracked_frames": [2, 3, 4]}
    fig = per_frame_figure({"zero-velocity": ["zero-velocity"]}, ["walk"], {("zero-velocity", "walk"): [run]})
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    for ax in fig.axes:
        box = ax.yaxis.label.get_window_extent(renderer)
        assert box.x0 >= 0 and box.y0 >= 0 and box.y1 <= fig.bbox.y1, (box, fig.bbox)


def test_the_colours_are_named_as_drawn():
    from tracker.app.visualize import CENTRE_COLOUR, COLOUR_NAMES, LEFT_COLOUR, RIGHT_COLOUR

    hues = {"red": 0, "light blue": 210, "yellow": 55}  # degrees
    for side, colour in (("left", LEFT_COLOUR), ("right", RIGHT_COLOUR), ("centre", CENTRE_COLOUR)):
        hue = colorsys.rgb_to_hsv(*(c / 255 for c in colour))[0] * 360
        assert abs((hue - hues[COLOUR_NAMES[side]] + 180) % 360 - 180) < 20, (side, hue)
    phrase = f"right {COLOUR_NAMES['right']}"
    for path in ("README.md", "docs/guide/sequences.md", "tracker/app/report_html.py", "tracker/app/visualize.py"):
        text = " ".join((REPO / path).read_text().split())
        assert phrase in text and "right blue" not in text, path


def test_report_html_records_the_command_as_typed(tmp_path, capsys, monkeypatch, quick_scale):
    seq = tiny_sequence(tmp_path / "seq", frames=5)
    experiment = tmp_path / "exp.toml"
    experiment.write_text(f'seed = 1\n[tracking]\nparticles = 10\nannealing_layers = 1\n'
                          f'[[sequence]]\nname = "walk"\npath = "{seq}"\n[[prior]]\nname = "zero-velocity"\n')
    argv = ["-q", "compare", str(experiment), "--no-videos", "--out", str(tmp_path / "out")]
    assert run_cli(argv, capsys)[0] == 0
    page = (tmp_path / "out" / "report.html").read_text()
    assert f"pose-tracker -q compare {experiment} --no-videos --out {tmp_path / 'out'}" in page
    assert "python -m tracker" not in page
    assert json.loads((tmp_path / "out" / "experiment.json").read_text())["complete"] is True
    main = type(sys)("__main__")
    main.__spec__ = type("Spec", (), {"name": "tracker.__main__"})()
    monkeypatch.setitem(sys.modules, "__main__", main)
    assert console.invoked_as() == "python -m tracker"


def test_a_frame_rate_mismatch_says_which_commands_fix_it():
    from priors.common import check_model_fits

    with pytest.raises(InputError) as refusal:
        check_model_fits("CRBM", ("cmu15", ["a"], 60.0), "cmu15", ["a"], 30.0)
    assert ("30 fps (trained at 60 fps; velocities are per frame): train the model at the sequence's rate "
            "(pose-tracker train ... --fps 30) or render the sequence at the model's (pose-tracker synth ... "
            "--fps 60)") in str(refusal.value)


@pytest.mark.slow
def test_a_borderline_retarget_residual_warns_and_points_to_the_advice(tmp_path, capsys, monkeypatch):
    import data_tools.motion.retarget as retargeting

    real = retargeting.retarget

    def off_by_25_mm(*args, **kwargs):
        result = real(*args, **kwargs)
        return dataclasses.replace(result, model_markers=result.model_markers + np.array([25.0, 0, 0]))

    code, err = run_cli(["convert", "--mocap", str(WALKS[0]), "--out", str(tmp_path / "good.npz")], capsys)
    assert code == 0 and "warning" not in err
    monkeypatch.setattr(retargeting, "retarget", off_by_25_mm)
    code, err = run_cli(["convert", "--mocap", str(WALKS[0]), "--out", str(tmp_path / "bad.npz")], capsys)
    warning = [line for line in err.splitlines() if "warning:" in line]
    assert code == 0 and len(warning) == 1, err
    assert re.search(r"mean retarget residual 2\d\.\d mm", warning[0]) and "--length-unit" in warning[0]
    assert "--joint-map" in warning[0] and "docs/guide/motion_capture.md" in warning[0]


def test_synthesize_from_python_names_the_keyword_not_the_flag(tmp_path):
    out = tmp_path / "seq"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError) as refusal:
        tracker.synthesize(WALKS[0], out, frames=3)
    assert "overwrite=True" in str(refusal.value) and "--overwrite" not in str(refusal.value)


def test_dir_of_the_package_lists_the_api_only():
    names = dir(tracker)
    assert not {"os", "importlib", "annotations", "_os", "_importlib"} & set(names)
    assert set(tracker.__all__) <= set(names) and "track" in names


def test_the_readme_says_how_fast_what_its_words_mean_and_where_the_cpu_torch_comes_from():
    text = " ".join((REPO / "README.md").read_text().split())
    assert "frames per second" in text and "on two cores" in text
    assert "--index-url https://download.pytorch.org/whl/cpu" in text and "only from an index that has it" in text
    for word in ("evidence", "paced", "IMM", "invariant representation"):
        assert f"**{word}**" in text, word
    assert "SIGTERM" in text and "143" in text
