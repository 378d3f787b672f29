"""Outputs are safe, one policy for every command that writes: an existing non-empty output (track's, compare's and
the demo's folders, train's, convert's, show's, initialise's and export's files, the API's ``result.save`` and
``model.save``) is refused unless the user says ``--overwrite`` (``overwrite=True``), a finished run's folder is
called one, an input is never written into even then, and the commands that continue their own earlier output
(``track --resume``, ``compare``) still do."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import tracker
from data_tools.samples import sample_walks
from tests.faults.test_bad_input_cli import one_line_refusal, run_cli
from tests.faults.test_bad_input_readers import tiny_sequence
from tests.app.test_compare import write_experiment
from tracker.app.compare import compare
from tracker.core.errors import InputError

ASF, WALKS = sample_walks()
AMC = str(WALKS[0])


@pytest.fixture
def seq(tmp_path):
    return tiny_sequence(tmp_path / "seq", frames=4)


def track_args(seq, out, *extra):
    return ["track", str(seq), "--prior", "zero-velocity", "--particles", "10", "--annealing-layers", "1",
            "--checkpoint-every", "0", "--out", str(out), *extra]


def test_track_refuses_a_non_empty_output_folder_unless_overwrite(seq, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    one_line_refusal(*run_cli(track_args(seq, out), capsys), str(out), "not empty (pass --overwrite")
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    (out / "prior_summary.png").write_bytes(b"an earlier run's plot")
    assert run_cli(track_args(seq, out, "--overwrite"), capsys)[0] == 0
    assert (out / "result.json").exists() and (out / "notes.txt").read_text() == "mine"
    assert not (out / "prior_summary.png").exists()  # zero-velocity has no per-frame summary


def test_a_finished_runs_folder_is_called_one(seq, tmp_path, capsys):
    out = tmp_path / "out"
    assert run_cli(track_args(seq, out), capsys)[0] == 0
    one_line_refusal(*run_cli(track_args(seq, out), capsys), str(out),
                     "holds a finished run (result.json) (pass --overwrite to replace it)")


def test_show_initialise_and_export_refuse_existing_files_unless_overwrite(seq, tmp_path, capsys):
    run = tmp_path / "run"
    assert run_cli(track_args(seq, run), capsys)[0] == 0
    commands = {
        "png": ["show", str(seq), "--out", str(tmp_path / "f.png")],
        "mp4": ["show", str(seq), "--video", str(tmp_path / "f.mp4")],
        "npz": ["initialise", str(seq), "--out", str(tmp_path / "init.npz")],
        "bvh": ["export", str(run), "--bvh", str(tmp_path / "p.bvh")],
        "trc": ["export", str(run), "--trc", str(tmp_path / "p.trc")],
    }
    for ext, argv in commands.items():
        earlier = tmp_path / Path(argv[-1]).name
        earlier.write_bytes(b"earlier")
        one_line_refusal(*run_cli(argv, capsys), earlier.name, "exists (pass --overwrite to replace it)")
        assert earlier.read_bytes() == b"earlier", ext
        status, err = run_cli([*argv, "--overwrite"], capsys)
        if ext == "npz":  # this tiny sequence cannot be initialised: what matters is that the file was no obstacle
            assert status == 2 and "exists" not in err and "cannot place the body" in err, err
            continue
        assert status == 0 and earlier.read_bytes() != b"earlier", ext


@pytest.mark.parametrize("where", ["seq", "seq/results"])
def test_track_never_writes_into_the_sequence_folder(where, seq, tmp_path, capsys):
    before = sorted(p.name for p in seq.rglob("*"))
    one_line_refusal(*run_cli(track_args(seq, tmp_path / where, "--overwrite"), capsys),
                     "would be written into the sequence folder")
    one_line_refusal(*run_cli(track_args(seq, tmp_path / "out", "--video", str(seq / "v.mp4")), capsys),
                     "would be written into the sequence folder")
    assert sorted(p.name for p in seq.rglob("*")) == before


def test_track_refuses_an_existing_video_unless_overwrite(seq, tmp_path, capsys):
    (tmp_path / "v.mp4").write_bytes(b"an earlier video")
    one_line_refusal(*run_cli(track_args(seq, tmp_path / "out", "--video", str(tmp_path / "v.mp4")), capsys),
                     "v.mp4", "exists (pass --overwrite")


@pytest.mark.slow
def test_train_refuses_an_existing_model_file_and_never_overwrites_its_clips(tmp_path, capsys):
    model = tmp_path / "m.pt"
    model.write_bytes(b"an earlier model")
    argv = ["train", "--prior", "crbm", "--mocap", AMC, "--order", "1", "--epochs", "1", "--hidden", "8"]
    one_line_refusal(*run_cli([*argv, "--out", str(model)], capsys), str(model), "exists (pass --overwrite")
    assert model.read_bytes() == b"an earlier model"
    clip = tmp_path / "07_01.amc"
    shutil.copy(AMC, clip)
    shutil.copy(ASF, tmp_path / ASF.name)
    one_line_refusal(*run_cli(["train", "--prior", "crbm", "--mocap", str(clip), "--overwrite", "--out", str(clip)],
                              capsys), "would be written into the training file 1")
    assert clip.read_bytes() == WALKS[0].read_bytes()
    assert run_cli([*argv, "--overwrite", "--out", str(model)], capsys)[0] == 0
    assert model.stat().st_size > 1000


@pytest.mark.slow
def test_convert_refuses_an_existing_output_unless_overwrite(tmp_path, capsys):
    out = tmp_path / "c.npz"
    out.write_bytes(b"earlier")
    one_line_refusal(*run_cli(["convert", "--mocap", AMC, "--out", str(out)], capsys), str(out),
                     "exists (pass --overwrite")
    assert out.read_bytes() == b"earlier"
    assert run_cli(["convert", "--mocap", AMC, "--overwrite", "--out", str(out)], capsys)[0] == 0
    assert out.stat().st_size > 1000


@pytest.mark.slow
def test_compare_refuses_a_folder_that_is_not_a_compare_output_unless_overwrite(tmp_path, capsys):
    path = write_experiment(tmp_path, priors=("zero-velocity",), seeds=1, tracking="particles = 10\nframes = 3")
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="not empty"):
        compare(path, out, say=lambda s: None, progress=False)
    one_line_refusal(*run_cli(["compare", str(path), "--out", str(out)], capsys), str(out), "--overwrite")
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    compare(path, out, overwrite=True, say=lambda s: None, progress=False)
    said = []  # now a compare output: continued without --overwrite, its finished run skipped
    compare(path, out, say=said.append, progress=False)
    assert any("1 finished before (skipped), 0 to run" in s for s in said) and (out / "notes.txt").exists()


def test_compare_never_writes_into_a_sequence_folder_of_the_experiment(seq, tmp_path):
    path = tmp_path / "exp.toml"
    path.write_text(f'seed = 1\nseeds = 1\n[tracking]\nparticles = 10\nframes = 3\n'
                    f'[[sequence]]\nname = "tiny"\npath = "{seq}"\n[[prior]]\nname = "zero-velocity"\n')
    with pytest.raises(InputError, match="would be written into the sequence folder of 'tiny'"):
        compare(path, seq / "results", overwrite=True, say=lambda s: None, progress=False)
    assert not (seq / "results").exists()


@pytest.mark.slow
def test_api_saves_refuse_existing_outputs_unless_overwrite(seq, tmp_path):
    result = tracker.track(seq, "zero-velocity", particles=10, annealing_layers=1)
    result.save(tmp_path / "run")
    with pytest.raises(InputError, match=r"holds a finished run \(result.json\) \(pass overwrite=True to replace it\)"):
        result.save(tmp_path / "run")
    result.save(tmp_path / "run", overwrite=True)
    with pytest.raises(InputError, match="would be written into the sequence folder"):
        result.save(seq, overwrite=True)
    model = tracker.train("crbm", [AMC], skeletons=[ASF], order=1, epochs=1, hidden=8)
    model.save(tmp_path / "m.pt")
    with pytest.raises(InputError, match=r"m.pt: the model file exists \(pass overwrite=True to replace it\)"):
        model.save(tmp_path / "m.pt")
    model.save(tmp_path / "m.pt", overwrite=True)


def test_the_demo_refuses_a_folder_that_holds_no_demo_output(tmp_path):
    from tracker.app.demo import run_demo

    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="holds no demo.json"):
        run_demo(tmp_path, frames=8)
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]
    take = tmp_path / "take"  # a capture's folder holds a sequence/ too: never the demo's, even with overwrite
    (take / "sequence").mkdir(parents=True)
    (take / "sequence" / "cameras.json").write_text("{}")
    with pytest.raises(InputError, match="holds no demo.json"):
        run_demo(take, frames=8, overwrite=True)
    assert (take / "sequence" / "cameras.json").read_text() == "{}"


@pytest.mark.slow
def test_the_demo_runs_again_into_its_own_folder_with_overwrite(tmp_path, capsys):
    from tracker.app import cli

    demo = ["demo", "--out", str(tmp_path / "demo"), "--frames", "6"]
    assert cli.main(demo) == 0
    before = (tmp_path / "demo" / "error_per_frame.png").read_bytes()
    one_line_refusal(*run_cli(demo, capsys), "demo", "holds an earlier demo's output (pass --overwrite to replace it)")
    assert (tmp_path / "demo" / "error_per_frame.png").read_bytes() == before
    (tmp_path / "demo" / "left_over.txt").write_text("an earlier version's file")
    assert cli.main([*demo, "--overwrite"]) == 0  # replaced whole
    assert sorted(p.name for p in (tmp_path / "demo").iterdir()) == [
        "demo.json", "error_per_frame.png", "overlay.mp4", "sequence",
        *(f"track_{prior}_seed{seed}" for prior in ("mixture", "zero-velocity") for seed in (0, 1, 2))]
