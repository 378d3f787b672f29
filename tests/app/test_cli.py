import json
import subprocess
import sys

import numpy as np
import pytest

from tracker.app.cli import main


def test_help_lists_commands():
    out = subprocess.run([sys.executable, "-m", "tracker", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    for command in ("convert", "synth", "show", "track", "demo"):
        assert command in out.stdout


def test_convert_writes_clip(mocap_dir, tmp_path, capsys):
    out = tmp_path / "clip.npz"
    assert main(["convert", "--mocap", str(mocap_dir / "07" / "07_02.amc"), "--fps", "30", "--out", str(out)]) == 0
    line = capsys.readouterr().out.strip()  # the result line: how the file was read and how well it fitted
    assert line.startswith("07_02.amc: CMU ASF names, lengths in ASF units of 56.44 mm, y up, 120 Hz; 83 frames at "
                           "30 fps, mean retarget residual") and line.count("\n") == 0
    with np.load(out) as d:
        assert d["poses"].shape == (83, 40) and d["markers"].shape == (83, 15, 3)
        assert d["model_markers"].shape == (83, 15, 3) and float(d["fps"]) == 30 and "lengths" in str(d["shape"])


@pytest.mark.slow
def test_convert_bad_inputs_exit_2(mocap_dir, tmp_path):
    amc = (mocap_dir / "07" / "07_01.amc").read_text().splitlines()
    broken = tmp_path / "07_01.amc"
    broken.write_text("\n".join(amc[:100]) + "\n")
    cases = [
        ["--mocap", str(broken), "--skeleton", str(mocap_dir / "07" / "07.asf")],
        ["--mocap", str(tmp_path / "missing.bvh")],
        ["--mocap", str(mocap_dir / "07" / "07_01.amc"), "--fps", "0"],
        ["--mocap", str(mocap_dir / "07" / "07_01.amc"), "--fps", "-5"],
        ["--mocap", str(mocap_dir / "07" / "07_01.amc"), "--fps", "1201"],  # more than 10 times the file's rate
    ]
    for args in cases:
        r = subprocess.run([sys.executable, "-m", "tracker", "convert", *args, "--out", str(tmp_path / "o.npz")],
                           capture_output=True, text=True)
        assert r.returncode == 2, args
        err = r.stderr.strip()
        assert err and "\n" not in err and "Traceback" not in err, err


@pytest.mark.slow
def test_demo(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--frames", "8"]) == 0
    printed = capsys.readouterr()
    assert "07_01" in printed.err and "mocap.cs.cmu.edu" in printed.out  # what it does on stderr, results on stdout
    (shows,) = [line for line in printed.out.splitlines() if line.startswith("What this shows: ")]
    assert "on CMU subject 7's walk 07_01, a person the pretrained model never saw" in shows
    assert "over 3 seeds" in shows
    for name in ("zero-velocity", "mixture"):
        for seed in (0, 1, 2):
            assert f"{name}, seed {seed}, 6 frames tracked: mpjpe_abs " in printed.out
            res = json.loads((tmp_path / f"track_{name}_seed{seed}" / "result.json").read_text())
            assert res["frames"] == 8 and res["frames_tracked"] == 6 and res["prior"] == name
            assert res["seed"] == seed and res["metrics"]["mpjpe_abs"]["mean"] < 100
    assert "Training" not in printed.err and "(no training)" in printed.err  # the default needs none
    assert (tmp_path / "overlay.mp4").stat().st_size > 1000 and (tmp_path / "error_per_frame.png").exists()
