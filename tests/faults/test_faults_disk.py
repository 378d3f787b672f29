"""A full disk, a read-only file system, no permission: every command's writes end in one line naming the file and
the cause, exit status 2, and leave what was complete before as it was (a checkpoint stays resumable).

Two ways to fill a disk: a real one (a 64 KiB tmpfs, filled up to a few KiB; needs root and a mount namespace that
allows it, skipped otherwise), and writers made to fail with ``ENOSPC``/``EROFS``/``EACCES`` (always run).
"""
from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tracker
from data_tools.samples import sample_walks
from tests.faults.test_bad_input_readers import tiny_sequence
from tracker.app import cli
from tracker.core.errors import InputError

ASF, WALKS = sample_walks()
AMC = str(WALKS[0])


def run_cli(argv: list[str], capsys) -> tuple[int, str]:
    capsys.readouterr()
    code = cli.main(argv)
    return code, capsys.readouterr().err


def refused(code: int, err: str, *fragments: str) -> str:
    """The one error line of a command that exited with status 2 (progress and log lines may come before it)."""
    errors = [line for line in err.replace("\r", "\n").splitlines() if "error:" in line]
    assert code == 2 and len(errors) == 1 and "Traceback" not in err, (code, err[-2000:])
    for f in fragments:
        assert f in errors[0], (f, errors[0])
    return errors[0]


def failing(cause: int, after: int = 0, when=lambda *args: True):
    """A stand-in writer that works ``after`` times (counting the calls ``when`` picks), then fails with
    ``OSError(cause)``."""
    calls = {"n": 0}

    def fail(original):
        def writer(*args, **kwargs):
            if when(*args):
                calls["n"] += 1
                if calls["n"] > after:
                    raise OSError(cause, os.strerror(cause))
            return original(*args, **kwargs)
        return writer
    return fail


@pytest.fixture
def seq(tmp_path):
    return tiny_sequence(tmp_path / "seq", frames=8)


def track_args(seq: Path, out: Path, *extra: str) -> list[str]:
    return ["track", str(seq), "--prior", "zero-velocity", "--particles", "20", "--annealing-layers", "1",
            "--out", str(out), *extra]


# -- a real full disk ----------------------------------------------------------------------------------------

@pytest.fixture
def full_disk(tmp_path):
    """A 64 KiB tmpfs filled up to 4 KiB: room for small files (the saved arguments), none for results."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a small tmpfs needs root")
    place = tmp_path / "full"
    place.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(place)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.decode().strip()[:80]})")
    try:
        stat = os.statvfs(place)
        (place / "filler").write_bytes(b"\0" * max(stat.f_bavail * stat.f_frsize - 4096, 0))
        yield place
    finally:
        subprocess.run(["umount", "-l", str(place)], capture_output=True)


def _no_temporary_files(folder: Path) -> None:
    left = [p.name for p in folder.rglob("*") if ".tmp" in p.name or p.name.startswith(".") and p.suffix != ".json"]
    assert not left, left


@pytest.mark.slow
def test_track_on_a_full_disk_is_one_line_and_leaves_no_half_written_file(seq, full_disk):
    argv = track_args(seq, full_disk / "out", "--checkpoint-every", "1")
    r = subprocess.run([sys.executable, "-m", "tracker", *argv], capture_output=True, text=True)
    refused(r.returncode, r.stderr, str(full_disk / "out"), "no space left on the device")
    _no_temporary_files(full_disk)


@pytest.mark.slow
@pytest.mark.parametrize("command", ["synth", "convert", "train", "compare"])
def test_every_command_on_a_full_disk_is_one_line(command, full_disk, tmp_path):
    from tests.app.test_compare import write_experiment

    argv = {
        "synth": ["synth", "--mocap", AMC, "--frames", "3", "--views", "1", "--out", str(full_disk / "s")],
        "convert": ["convert", "--mocap", AMC, "--out", str(full_disk / "c.npz")],
        "train": ["train", "--prior", "crbm", "--mocap", AMC, "--order", "1", "--epochs", "1", "--hidden", "8",
                  "--out", str(full_disk / "m.pt")],
        "compare": ["compare", str(write_experiment(tmp_path, priors=("zero-velocity",), seeds=1,
                                                    tracking="particles = 10\nframes = 3")),
                    "--out", str(full_disk / "cmp")],
    }[command]
    r = subprocess.run([sys.executable, "-m", "tracker", *argv], capture_output=True, text=True)
    refused(r.returncode, r.stderr, str(full_disk), "no space left on the device")
    _no_temporary_files(full_disk)
    assert not (full_disk / "c.npz").exists() and not (full_disk / "m.pt").exists()


# -- writers that fail ------------------------------------------------------------------------------------------

def test_a_full_disk_while_checkpointing_keeps_the_last_checkpoint_resumable(seq, tmp_path, capsys, monkeypatch):
    import tracker.app.checkpoint as checkpoint

    assert run_cli(track_args(seq, tmp_path / "whole", "--checkpoint-every", "1"), capsys)[0] == 0
    out = tmp_path / "cut"
    monkeypatch.setattr(checkpoint.np, "savez", failing(errno.ENOSPC, after=3)(np.savez))
    line = refused(*run_cli(track_args(seq, out, "--checkpoint-every", "1"), capsys),
                   str(out / "checkpoint.npz"), "no space left on the device", "the previous checkpoint is kept")
    assert line.count("\n") == 0
    monkeypatch.undo()
    with np.load(out / "checkpoint.npz") as saved:  # the third frame's state, intact
        assert json.loads(str(saved["meta"]))["tracked"] == 3
    assert run_cli(["track", "--resume", str(out)], capsys)[0] == 0
    with np.load(out / "estimates.npz") as a, np.load(tmp_path / "whole" / "estimates.npz") as b:
        assert np.array_equal(a["poses"], b["poses"])


@pytest.mark.parametrize("cause, said", [(errno.ENOSPC, "no space left on the device"),
                                         (errno.EROFS, "read-only file system"),
                                         (errno.EACCES, "permission denied")])
def test_track_results_that_cannot_be_written_are_one_line(cause, said, seq, tmp_path, capsys, monkeypatch):
    import tracker.app.tracking as tracking

    out = tmp_path / "out"
    out.mkdir()
    (out / "result.json").write_text("{}")  # an earlier result, kept as it was
    monkeypatch.setattr(tracking, "write_estimates", failing(cause)(tracking.write_estimates))
    refused(*run_cli(track_args(seq, out, "--overwrite", "--checkpoint-every", "0"), capsys),
            str(out / "estimates.npz"), said)
    assert (out / "result.json").read_text() == "{}" and not (out / "estimates.npz").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".estimates")]


def test_an_overlay_video_that_cannot_be_written_is_one_line(seq, tmp_path, capsys, monkeypatch):
    import av

    monkeypatch.setattr(av, "open", failing(errno.ENOSPC)(av.open))
    refused(*run_cli(track_args(seq, tmp_path / "out", "--frames", "4", "--video", str(tmp_path / "v.mp4")), capsys),
            str(tmp_path / "v.mp4"), "no space left")
    assert (tmp_path / "out" / "result.json").exists() and not (tmp_path / "v.mp4").exists()


@pytest.mark.slow
def test_synth_images_that_cannot_be_written_are_one_line_and_keep_the_earlier_sequence(tmp_path, capsys,
                                                                                         monkeypatch):
    assert run_cli(["synth", "--mocap", AMC, "--frames", "2", "--views", "1", "--width", "64", "--height", "48",
                    "--out", str(tmp_path / "s")], capsys)[0] == 0
    before = sorted(p.name for p in (tmp_path / "s").rglob("*"))
    monkeypatch.setattr(Path, "write_bytes", failing(errno.ENOSPC, after=2)(Path.write_bytes))
    refused(*run_cli(["synth", "--mocap", AMC, "--frames", "3", "--views", "1", "--width", "64", "--height", "48",
                      "--overwrite", "--out", str(tmp_path / "s")], capsys),
            str(tmp_path / "s"), "no space left", "an earlier sequence there is kept")
    assert sorted(p.name for p in (tmp_path / "s").rglob("*")) == before
    assert [p.name for p in tmp_path.iterdir()] == ["s"]  # no temporary folder left


@pytest.mark.slow
def test_convert_on_a_read_only_file_system_is_one_line(tmp_path, capsys, monkeypatch):
    import data_tools.io.files as files

    monkeypatch.setattr(files.os, "replace", failing(errno.EROFS)(os.replace))
    refused(*run_cli(["convert", "--mocap", AMC, "--out", str(tmp_path / "c.npz")], capsys),
            str(tmp_path / "c.npz"), "read-only file system")
    assert list(tmp_path.iterdir()) == []


def test_a_model_file_that_cannot_be_written_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(Path, "write_bytes", failing(errno.ENOSPC)(Path.write_bytes))
    refused(*run_cli(["train", "--prior", "crbm", "--mocap", AMC, "--order", "1", "--epochs", "1", "--hidden", "8",
                      "--out", str(tmp_path / "m.pt")], capsys), str(tmp_path / "m.pt"), "no space left")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_a_training_checkpoint_that_cannot_be_written_keeps_the_earlier_one(tmp_path, monkeypatch):
    settings = dict(skeletons=[ASF], order=1, epochs=6, hidden=8, seed=0, checkpoint_every=2)
    checkpoint = tmp_path / "m.pt.checkpoint"
    monkeypatch.setattr(Path, "write_bytes", failing(errno.ENOSPC, after=1)(Path.write_bytes))
    with pytest.raises(InputError, match="m.pt.checkpoint: cannot write: no space left on the device; any earlier"):
        tracker.train("crbm", [AMC], checkpoint=checkpoint, **settings)
    monkeypatch.undo()
    resumed = tracker.train("crbm", [AMC], checkpoint=checkpoint, resume=True, **settings)  # from epoch 2
    whole = tracker.train("crbm", [AMC], **settings)
    assert resumed.reconstruction_errors == whole.reconstruction_errors


@pytest.mark.slow
def test_compare_runs_that_cannot_be_written_are_one_line_and_finished_runs_stay(tmp_path, monkeypatch):
    import tracker.app.tracking as tracking
    from tests.app.test_compare import run_numbers, write_experiment
    from tracker.app.compare import compare

    path = write_experiment(tmp_path, priors=("zero-velocity",), seeds=3, tracking="particles = 10\nframes = 3")
    monkeypatch.setattr(tracking, "write_estimates", failing(errno.ENOSPC, after=1)(tracking.write_estimates))
    with pytest.raises(InputError, match=r"runs/[0-9a-f]+/estimates.npz: cannot write: no space left"):
        compare(path, tmp_path / "out", say=lambda s: None, progress=False)
    finished = run_numbers(tmp_path / "out")
    assert len(finished) == 1 and not [p for p in (tmp_path / "out" / "runs").iterdir() if p.name.startswith(".")]
    monkeypatch.undo()
    said = []
    compare(path, tmp_path / "out", say=said.append, progress=False)
    assert any("3 runs: 1 finished before (skipped), 2 to run" in s for s in said)
    assert run_numbers(tmp_path / "out").items() >= finished.items()


@pytest.mark.slow
def test_compare_tables_that_cannot_be_written_are_one_line(tmp_path, monkeypatch):
    from tests.app.test_compare import write_experiment
    from tracker.app.compare import compare

    path = write_experiment(tmp_path, priors=("zero-velocity",), seeds=1, tracking="particles = 10\nframes = 3")
    import data_tools.io.files as files

    monkeypatch.setattr(files.os, "replace", failing(errno.EDQUOT, when=lambda tmp, dst: Path(dst).name ==
                                                     "table.md")(os.replace))
    with pytest.raises(InputError, match="table.md: cannot write: disk quota exceeded"):
        compare(path, tmp_path / "out", say=lambda s: None, progress=False)
    assert len(list((tmp_path / "out" / "runs").iterdir())) == 1  # the finished run stays


def test_results_that_cannot_be_written_leave_the_finished_run_resumable(seq, tmp_path, capsys, monkeypatch):
    import tracker.app.tracking as tracking

    assert run_cli(track_args(seq, tmp_path / "whole", "--checkpoint-every", "2"), capsys)[0] == 0
    out = tmp_path / "cut"
    monkeypatch.setattr(tracking, "write_estimates", failing(errno.ENOSPC)(tracking.write_estimates))
    refused(*run_cli(track_args(seq, out, "--checkpoint-every", "2"), capsys), "estimates.npz", "no space left")
    monkeypatch.undo()
    assert (out / "checkpoint.npz").exists()  # the tracked frames are not lost with the result
    assert run_cli(["track", "--resume", str(out)], capsys)[0] == 0
    with np.load(out / "estimates.npz") as a, np.load(tmp_path / "whole" / "estimates.npz") as b:
        assert np.array_equal(a["poses"], b["poses"])
    assert not (out / "checkpoint.npz").exists() and not (tmp_path / "whole" / "checkpoint.npz").exists()


def test_an_unreadable_input_is_not_taken_for_a_failed_write(tmp_path):
    """Permission denied on a file the block read (outside the output's folder) keeps its own error."""
    from data_tools.io.files import writing

    (tmp_path / "out").mkdir()
    with pytest.raises(PermissionError):
        with writing(tmp_path / "out" / "result.json"):
            raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "input.png"))
    with pytest.raises(InputError, match="result.json: cannot write: permission denied"):
        with writing(tmp_path / "out" / "result.json"):
            raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "out" / ".result.x.json"))
