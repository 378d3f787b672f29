"""Bad input on the command line (found by benchmarks/bad_input_corpus.py): one regression case per
failure the corpus found, run in-process through ``tracker.app.cli.main``.

Every refusal is exit status 2 with exactly one line on stderr that names the file or flag (and the range a value
must lie in), printed before any long work starts (no progress bar before it).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from data_tools.samples import sample_walks
from tests.faults.test_bad_input_readers import _png_claiming, tiny_sequence
from tracker.app import api, cli

ASF, WALKS = sample_walks()
AMC = str(WALKS[0])


def run_cli(argv: list[str], capsys) -> tuple[int, str]:
    """Exit status and stderr of ``python -m tracker ARGV`` run in this process."""
    capsys.readouterr()
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse refusals
        code = exc.code
    return code, capsys.readouterr().err


def one_line_refusal(code: int, err: str, *fragments: str) -> str:
    lines = [s for s in err.splitlines() if s.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, (code, err)
    for f in fragments:
        assert f in lines[0], (f, lines[0])
    return lines[0]


@pytest.mark.parametrize("argv, fragments", [
    (["convert", "--mocap", AMC, "--fps", "1e-300", "--out", "x.npz"], ("--fps", "at least 0.1 and at most 100000")),
    (["convert", "--mocap", AMC, "--fps", "1e308", "--out", "x.npz"], ("--fps", "at most 100000")),
    (["convert", "--mocap", AMC, "--length-unit", "1e308", "--out", "x.npz"], ("--length-unit", "at most 10000")),
    (["synth", "--mocap", AMC, "--width", "1000000000", "--out", "s"], ("--width", "at most 20000")),
    (["synth", "--mocap", AMC, "--cameras", "1000000000", "--out", "s"], ("--cameras", "at most 64")),
    (["synth", "--mocap", AMC, "--noise", "1e308", "--out", "s"], ("--noise", "at most 255")),
    (["synth", "--mocap", AMC, "--lighting-change", "1e308", "--out", "s"], ("--lighting-change", "less than 2")),
    (["synth", "--mocap", AMC, "--lighting-change", "-5", "--out", "s"], ("--lighting-change", "greater than -0.9")),
    (["synth", "--mocap", AMC, "--seed", str(2 ** 70), "--out", "s"], ("--seed", "at most 9223372036854775807")),
    (["train", "--prior", "gpdm", "--mocap", AMC, "--seed", str(2 ** 64), "--out", "m.pt"], ("--seed",)),
    (["track", "s", "--prior", "zero-velocity", "--particles", "1000000000000", "--out", "o"],
     ("--particles", "at most 1000000")),
    (["track", "s", "--prior", "zero-velocity", "--annealing-layers", "1000000000", "--out", "o"],
     ("--annealing-layers", "at most 100")),
    (["track", "s", "--prior", "gpdm", "--latent-noise", "1e308", "--out", "o"], ("--latent-noise", "at most 100")),
    (["track", "s", "--prior", "zero-velocity", "--prior-scale", "1e308", "--out", "o"],
     ("--prior-scale", "at most 1000")),
])
def test_absurd_values_are_refused_with_their_range(argv, fragments, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the relative output names must not land in the checkout if a refusal regresses
    one_line_refusal(*run_cli(argv, capsys), *fragments)


def test_gpdm_root_noise_bound_holds_whichever_prior_declares_the_flag_first():
    """``--root-noise`` is shared by several priors; the GPDM checks its own bound when it is built."""
    from tracker.app.api import prior_entry
    from tracker.core.errors import InputError
    from tracker.engine.registry import resolve_options

    with pytest.raises(InputError, match="root_noise must be at least 0 and at most 1000"):
        resolve_options("prior gpdm", prior_entry("gpdm").options, {"root_noise": 1e308})


@pytest.fixture
def seq(tmp_path):
    return tiny_sequence(tmp_path / "seq", frames=3)


def _track(seq, tmp_path, *extra: str) -> list[str]:
    return ["track", str(seq), "--prior", "zero-velocity", "--particles", "10", "--checkpoint-every", "0",
            "--out", str(tmp_path / "out"), *extra]


def test_refusals_found_while_tracking_starts_come_before_the_progress_bar(seq, tmp_path, capsys):
    init = tmp_path / "init.npz"
    np.savez(init, poses=np.zeros((2, 1)))
    one_line_refusal(*run_cli(_track(seq, tmp_path, "--init", str(init)), capsys), "init.npz", "poses must have shape")
    one_line_refusal(*run_cli(_track(seq, tmp_path, "--known-frames", "1000"), capsys), "known frames 1000",
                     "the run has 3 frame(s) and 3 of them would be known")
    assert not (tmp_path / "out" / "estimates.npz").exists()


def test_a_broken_background_plate_is_refused_when_the_sequence_is_read(seq, tmp_path, capsys):
    (seq / "background" / "cam0.png").write_bytes(_png_claiming(100000, 100000))
    one_line_refusal(*run_cli(_track(seq, tmp_path), capsys), "cam0.png", "100000x100000")
    one_line_refusal(*run_cli(["show", str(seq), "--out", str(tmp_path / "f.png")], capsys), "cam0.png")


def test_images_of_a_camera_missing_from_cameras_json_are_refused(seq, tmp_path, capsys):
    rig = json.loads((seq / "cameras.json").read_text())
    rig["cameras"] = rig["cameras"][:1]
    (seq / "cameras.json").write_text(json.dumps(rig))
    one_line_refusal(*run_cli(_track(seq, tmp_path), capsys), "cameras.json", "images/cam1/")


@pytest.mark.parametrize("command", ["convert", "train", "show", "video", "track", "track --video", "synth"])
def test_an_unwritable_output_is_refused_before_any_work(command, seq, tmp_path, capsys):
    place = "/proc/pose-tracker-test"  # nothing can be created here, not even by root
    argv = {
        "convert": ["convert", "--mocap", AMC, "--out", f"{place}/c.npz"],
        "train": ["train", "--prior", "crbm", "--mocap", AMC, "--epochs", "1", "--out", f"{place}/m.pt"],
        "show": ["show", str(seq), "--out", f"{place}/f.png"],
        "video": ["show", str(seq), "--video", f"{place}/v.mp4"],
        "track": _track(seq, tmp_path)[:-2] + ["--out", f"{place}/out"],
        "track --video": _track(seq, tmp_path, "--video", f"{place}/v.mp4"),
        "synth": ["synth", "--mocap", AMC, "--frames", "2", "--out", f"{place}/s"],
    }[command]
    capsys.readouterr()
    one_line_refusal(*run_cli(argv, capsys), place, "not writable")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("failure", [
    MemoryError("Unable to allocate 291. TiB for an array with shape (1000000000000, 40)"),  # numpy
    RuntimeError("[enforce fail at alloc_cpu.cpp:127] err == 0. DefaultCPUAllocator: can't allocate memory: you "
                 "tried to allocate 156000000000000 bytes."),  # torch
])
def test_running_out_of_memory_is_one_line(failure, monkeypatch, capsys, tmp_path):
    monkeypatch.chdir(tmp_path)

    def greedy(args):
        raise failure

    from tracker.app.commands import convert

    monkeypatch.setattr(convert, "run", greedy)
    one_line_refusal(*run_cli(["convert", "--mocap", AMC, "--out", "x.npz"], capsys), "not enough memory")
    monkeypatch.setattr(convert, "run", lambda args: (_ for _ in ()).throw(RuntimeError("a bug")))
    with pytest.raises(RuntimeError, match="a bug"):  # other runtime errors are not taken for bad input
        cli.main(["convert", "--mocap", AMC, "--out", "x.npz"])


@pytest.mark.slow
def test_ctrl_c_in_training_says_how_to_resume(monkeypatch, tmp_path, capsys):
    def interrupted(*args, **kwargs):
        (tmp_path / "m.pt.checkpoint").write_bytes(b"state")
        raise KeyboardInterrupt

    monkeypatch.setattr(api, "train", interrupted)
    code, err = run_cli(["train", "--prior", "gpdm", "--mocap", AMC, "--checkpoint-every", "10", "--out",
                         str(tmp_path / "m.pt")], capsys)
    assert code == 130 and "--resume" in err and "Traceback" not in err and not (tmp_path / "m.pt").exists()
