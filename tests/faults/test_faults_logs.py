"""What a command leaves on stderr and on disk when things go wrong or nobody watches: progress in a log (stderr
not a terminal) is a plain line now and then, not a redrawn bar; an error is the last line, with no bar drawn
again below it; and a refused command leaves nothing behind that was not there before."""
from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from data_tools.samples import sample_walks
from tests.faults.test_bad_input_readers import tiny_sequence
from tests.faults.test_faults_disk import failing, refused, run_cli, track_args
from tracker.app import cli, console

ASF, WALKS = sample_walks()
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def seq(tmp_path):
    return tiny_sequence(tmp_path / "seq", frames=8)


@pytest.mark.slow
def test_train_into_a_log_writes_a_few_progress_lines_not_bars(tmp_path):
    """A default-sized training reports 1,000 updates; its log holds a line at most every tenth of the work."""
    log = tmp_path / "train.log"
    with open(log, "w") as err:
        r = subprocess.run([sys.executable, "-m", "tracker", "train", "--prior", "crbm", "--mocap", str(WALKS[0]),
                            "--order", "1", "--hidden", "4", "--epochs", "300", "--batch-size", "1000",
                            "--out", str(tmp_path / "m.pt")], stdout=subprocess.PIPE, stderr=err, text=True,
                           env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=300)
    text = log.read_text()
    assert r.returncode == 0, text[-2000:]
    lines = text.splitlines()
    assert "\r" not in text and "\x1b" not in text  # no bar redrawn in place
    progress = [line for line in lines if line.startswith("training crbm: ")]
    assert 1 <= len(progress) <= 11 and progress[-1].startswith("training crbm: 300/300 its (100%)"), text
    assert len(lines) <= 14 and len(text) < 2000, text


def test_progress_lines_come_a_tenth_of_the_work_apart_and_never_more_often_than_every_few_seconds(monkeypatch,
                                                                                                   caplog):
    clock = {"t": 0.0}
    monkeypatch.setattr(console.time, "monotonic", lambda: clock["t"])
    monkeypatch.setattr(console, "on_terminal", lambda: False)
    caplog.set_level("INFO", logger="tracker")
    bar = console.progress_bar(total=1000, desc="training", unit="it", shown=True)
    for _ in range(1000):  # 1,000 updates 0.1 s apart: 100 s, a line every 100 updates (10 s)
        clock["t"] += 0.1
        bar.update(1)
    bar.close()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 10 and lines[0].startswith("training: 100/1000 its (10%), 10 it/s"), lines
    caplog.clear()
    bar = console.progress_bar(total=1000, desc="fast", unit="it", shown=True)
    for _ in range(1000):  # the same work in 2 s: one line, at the end
        clock["t"] += 0.002
        bar.update(1)
    bar.close()
    assert [r.getMessage() for r in caplog.records] == ["fast: 1000/1000 its (100%), 500 it/s"]


def test_quiet_shows_no_progress(seq, tmp_path, capsys, monkeypatch):
    for terminal in (True, False):
        monkeypatch.setattr(console, "on_terminal", lambda: terminal)
        code, err = run_cli(["-q", *track_args(seq, tmp_path / f"out{terminal}", "--frames", "5")], capsys)
        assert code == 0 and err == "", err


def test_an_error_after_the_bar_is_the_last_line_on_a_terminal(seq, tmp_path, capsys, monkeypatch):
    import gc

    import tracker.app.checkpoint as checkpoint

    monkeypatch.setattr(console, "on_terminal", lambda: True)
    monkeypatch.setattr(checkpoint.np, "savez", failing(errno.ENOSPC, after=3)(np.savez))
    capsys.readouterr()
    code = cli.main(track_args(seq, tmp_path / "out", "--checkpoint-every", "1"))
    gc.collect()  # a bar left open would draw itself again when collected
    err = capsys.readouterr().err
    lines = [line for line in err.replace("\r", "\n").splitlines() if line.strip()]
    assert code == 2 and "tracking (zero-velocity)" in err  # the bar was drawn
    assert "error:" in lines[-1] and "no space left on the device" in lines[-1], lines[-3:]


@pytest.mark.parametrize("model", ["fake", "missing", "none"])
def test_a_refused_track_leaves_no_output_folder(model, seq, tmp_path, capsys):
    (tmp_path / "fake.pt").write_bytes(b"not a model")
    out = tmp_path / "runs" / "x"
    given = {"fake": ["--model", str(tmp_path / "fake.pt")], "missing": ["--model", str(tmp_path / "nope.pt")],
             "none": []}[model]
    code, err = run_cli(["track", str(seq), "--prior", "crbm", *given, "--out", str(out)], capsys)
    refused(code, err)
    assert not (tmp_path / "runs").exists()


def test_a_refused_track_into_an_existing_empty_folder_leaves_it_empty(seq, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    refused(*run_cli(["track", str(seq), "--prior", "crbm", "--out", str(out)], capsys))
    assert out.is_dir() and not any(out.iterdir())


def test_a_refused_train_leaves_nothing(tmp_path, capsys):
    out = tmp_path / "models" / "m.pt"
    refused(*run_cli(["train", "--prior", "crbm", "--mocap", str(WALKS[0]), "--order", "1", "--epochs", "2",
                      "--hidden", "4", "--checkpoint-every", "1", "--history-noise", "-1", "--out", str(out)], capsys))
    assert not (tmp_path / "models").exists()


def test_a_refused_compare_leaves_no_output_folder(seq, tmp_path, capsys):
    experiment = tmp_path / "exp.toml"
    experiment.write_text(f'seed = 1\n[tracking]\nparticles = 20\nviews = [0, 7]\n'
                          f'[[sequence]]\nname = "walk"\npath = "{seq}"\n[[prior]]\nname = "zero-velocity"\n')
    refused(*run_cli(["compare", str(experiment), "--out", str(tmp_path / "out")], capsys), "views [0, 7]")
    assert not (tmp_path / "out").exists()
