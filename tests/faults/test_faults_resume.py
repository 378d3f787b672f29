"""A resume refuses inputs that changed since the interruption: the sequence's images, a model file, the package
version (``track --resume``), a training clip (``train --resume``); each in one line naming what changed. The
sequence's content hashes are cached in the output folder, so an unchanged resume hashes nothing again."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import tracker
from data_tools.samples import sample_walks
from data_tools.sequences.sequence import frame_path, write_image
from tests.faults.test_bad_input_readers import tiny_sequence
from tests.faults.test_faults_disk import refused, run_cli, track_args
from tracker.app import api
from tracker.app.tracking import TrackingInterrupted
from tracker.core.errors import InputError

ASF, WALKS = sample_walks()


@pytest.fixture
def seq(tmp_path):
    return tiny_sequence(tmp_path / "seq", frames=8)


def interrupt_after(frames: int, monkeypatch) -> None:
    """The command line's next ``track`` is interrupted (Ctrl-C) after ``frames`` tracked frames."""
    real = api.track

    def track(*args, on_frame=None, **kwargs):
        count = {"n": 0}

        def frame(step, err):
            on_frame(step, err)
            count["n"] += 1
            if count["n"] == frames:
                raise KeyboardInterrupt
        return real(*args, on_frame=frame, **kwargs)

    monkeypatch.setattr(api, "track", track)


def interrupted_run(seq: Path, out: Path, capsys, monkeypatch) -> None:
    interrupt_after(3, monkeypatch)
    code, err = run_cli(track_args(seq, out, "--checkpoint-every", "1"), capsys)
    assert code == 130 and "--resume" in err, err
    monkeypatch.undo()


def test_an_unchanged_resume_reuses_the_cached_hashes_and_gives_the_uninterrupted_result(seq, tmp_path, capsys,
                                                                                          monkeypatch):
    import data_tools.io.fingerprints as fingerprints

    assert run_cli(track_args(seq, tmp_path / "whole", "--checkpoint-every", "1"), capsys)[0] == 0
    out = tmp_path / "cut"
    interrupted_run(seq, out, capsys, monkeypatch)
    hashed = []
    monkeypatch.setattr(fingerprints, "file_hash", lambda p: hashed.append(p) or "0" * 64)
    assert run_cli(["track", "--resume", str(out)], capsys)[0] == 0
    assert hashed == []  # every file's hash came from the cache in the output folder
    with np.load(out / "estimates.npz") as a, np.load(tmp_path / "whole" / "estimates.npz") as b:
        assert np.array_equal(a["poses"], b["poses"])


def test_a_resume_after_half_the_images_were_replaced_is_refused(seq, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    interrupted_run(seq, out, capsys, monkeypatch)
    for k in range(4):  # half of camera 0's frames, same size and name, other content
        write_image(frame_path(seq, "cam0", k), np.full((24, 32, 3), 7, np.uint8))
    line = refused(*run_cli(["track", "--resume", str(out)], capsys), str(out / "checkpoint.npz"),
                   "cannot resume", "4 of the sequence's", "images/cam0/000000.png", "start the run again")
    assert "model" not in line and "version" not in line
    assert (out / "checkpoint.npz").exists()  # kept: restoring the images makes it resumable again


def test_a_resume_after_a_file_was_added_or_removed_is_refused(seq, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    interrupted_run(seq, out, capsys, monkeypatch)
    (seq / "groundtruth.npz").rename(tmp_path / "gt.npz")
    (tmp_path / "gt.npz").rename(seq / "groundtruth.npz")  # moved away and back: same content, resumes
    (seq / "notes.txt").write_text("added")
    refused(*run_cli(["track", "--resume", str(out)], capsys), "1 of the sequence's", "notes.txt")


@pytest.fixture(scope="module")
def crbm_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("models")
    for seed in (0, 1):
        tracker.train("crbm", [WALKS[0]], skeletons=[ASF], order=1, epochs=2, hidden=8, seed=seed).save(
            folder / f"c{seed}.pt")
    return folder


@pytest.mark.slow
def test_a_resume_after_the_model_file_was_replaced_is_refused(seq, crbm_files, tmp_path):
    model = tmp_path / "crbm.pt"
    shutil.copy(crbm_files / "c0.pt", model)
    checkpoint = tmp_path / "out" / "checkpoint.npz"
    settings = dict(models=[model], particles=10, annealing_layers=1, seed=0, checkpoint=checkpoint)

    def stop(step, err):
        if step.frame == 4:
            raise KeyboardInterrupt

    with pytest.raises(TrackingInterrupted):
        tracker.track(seq, "crbm", on_frame=stop, checkpoint_every=1, **settings)
    shutil.copy(crbm_files / "c1.pt", model)  # another training, same path
    with pytest.raises(InputError, match=rf"cannot resume: since the checkpoint was written, the model file {model} "
                                         "changed; start"):
        tracker.track(seq, "crbm", resume=True, **settings)
    shutil.copy(crbm_files / "c0.pt", model)
    assert tracker.track(seq, "crbm", resume=True, **settings).first_tracked == 2


def test_a_resume_by_another_version_is_refused(seq, tmp_path, monkeypatch):
    checkpoint = tmp_path / "out" / "checkpoint.npz"

    def stop(step, err):
        if step.frame == 3:
            raise KeyboardInterrupt

    with pytest.raises(TrackingInterrupted):
        tracker.track(seq, "zero-velocity", particles=10, annealing_layers=1, checkpoint=checkpoint,
                      checkpoint_every=1, on_frame=stop)
    monkeypatch.setattr(tracker, "__version__", "99.0")
    with pytest.raises(InputError, match=r"since the checkpoint was written, pose-tracker changed from version .* "
                                         "to 99.0"):
        tracker.track(seq, "zero-velocity", particles=10, annealing_layers=1, checkpoint=checkpoint, resume=True)


@pytest.mark.slow
def test_train_resume_after_a_training_clip_changed_is_refused(tmp_path):
    clips = tmp_path / "clips"
    clips.mkdir()
    for f in (WALKS[0], ASF):
        shutil.copy(f, clips / f.name)
    amc = clips / WALKS[0].name
    checkpoint = tmp_path / "m.pt.checkpoint"
    settings = dict(order=1, epochs=6, hidden=8, seed=0, checkpoint_every=2)

    def stop(done, total, metrics):
        if done == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        tracker.train("crbm", [amc], checkpoint=checkpoint, progress=stop, **settings)
    original = amc.read_text()
    amc.write_text(original + "\n")  # one more byte: another file, the same motion
    with pytest.raises(InputError, match=rf"cannot resume: since the checkpoint was written, the training file {amc} "
                                         "changed; start the training"):
        tracker.train("crbm", [amc], checkpoint=checkpoint, resume=True, **settings)
    amc.write_text(original)
    resumed = tracker.train("crbm", [amc], checkpoint=checkpoint, resume=True, **settings)
    assert resumed.reconstruction_errors == tracker.train("crbm", [amc], **settings).reconstruction_errors
    assert not checkpoint.exists() and not Path(f"{checkpoint}.inputs.json").exists()


@pytest.mark.slow
def test_train_resume_on_the_command_line_names_the_changed_skeleton(tmp_path, capsys):
    clips = tmp_path / "clips"
    clips.mkdir()
    for f in (WALKS[0], ASF):
        shutil.copy(f, clips / f.name)
    out = tmp_path / "m.pt"
    argv = ["train", "--prior", "crbm", "--mocap", str(clips / WALKS[0].name), "--order", "1", "--epochs", "4",
            "--hidden", "8", "--checkpoint-every", "2", "--out", str(out)]
    real = api.train

    def interrupted(*args, progress=None, **kwargs):
        def stop(done, total, metrics):
            if done == 3:
                raise KeyboardInterrupt
        return real(*args, progress=stop, **kwargs)

    api.train = interrupted
    try:
        assert run_cli(argv, capsys)[0] == 130
    finally:
        api.train = real
    skeleton = clips / ASF.name
    skeleton.write_text(skeleton.read_text() + "\n")
    refused(*run_cli([*argv, "--resume"], capsys), f"the training file {skeleton} changed", "start the training again")
