"""compare on a sequence folder without ground truth (as import-video writes one): its first poses from ``init``,
tables of what can be said without a marker error, each run's distance to a reference reconstruction measured as
compare-trc measures it, the report's overlays over the sequence's own frames, and one line for a missing or bad
start or reference."""
import base64
import io
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from data_tools.motion.trc import write_trc
from data_tools.sequences.reference import POSE2SIM_MAP, compare_to_trc
from tracker.app.cli import main
from tracker.core.body import MARKER_NAMES

SAMPLE = Path(__file__).resolve().parents[2] / "data_tools" / "samples" / "cmu07"
MAPPED = [m for m in MARKER_NAMES if m in POSE2SIM_MAP]


@pytest.fixture(scope="module")
def folder(small_walk, tmp_path_factory) -> Path:
    """A rendered walk (2 views, 5 frames) with its ground truth removed, its first two poses as ``init.npz``
    and its true markers written as a Pose2Sim-style TRC (``ref.trc``) that starts one frame before it."""
    from data_tools.sequences.sequence import read_sequence

    root = tmp_path_factory.mktemp("no_truth")
    shutil.copytree(small_walk, root / "seq")
    truth = read_sequence(root / "seq").groundtruth
    (root / "walk").mkdir()  # the random walks' scale from 30 frames of a shipped walk: quicker than the default
    shutil.copy(SAMPLE / "07.asf", root / "walk")
    text = (SAMPLE / "07_01.amc").read_text()
    (root / "walk" / "07_01.amc").write_text(text[:text.index("\n31\n") + 1])
    (root / "seq" / "groundtruth.npz").unlink()
    np.savez(root / "init.npz", poses=truth.poses[:2])
    points = truth.markers[:, [MARKER_NAMES.index(m) for m in MAPPED]]
    write_trc(root / "ref.trc", [POSE2SIM_MAP[m][0] for m in MAPPED],
              np.concatenate([points[:1] + 300.0, points]), 60.0)
    return root


def experiment(root: Path, sequence: str, name: str = "exp.toml", scale: bool = True) -> Path:
    """Two priors, 2 seeds, 30 particles, 4 frames on the sequence folder ``seq`` with the keys ``sequence``;
    ``scale``: the random walks' scale from a few frames of a shipped walk (quicker than the default clips)."""
    clip = 'train_mocap = ["walk/07_01.amc"]' if scale else ""
    path = root / name
    path.write_text(f'''seed = 3
seeds = 2
[tracking]
particles = 30
frames = 4
[[sequence]]
name = "imported"
path = "seq"
{sequence}
[[prior]]
name = "zero-velocity"
{clip}
[[prior]]
name = "constant-velocity"
{clip}
''')
    return path


def test_a_start_and_a_reference_that_cannot_serve_are_one_line_before_anything_runs(folder, capsys):
    (folder / "short.trc").write_text("PathFileType\t4\n")
    write_trc(folder / "other.trc", ["Nose", "LEye", "REye"], np.zeros((3, 3, 3)), 60.0)
    for sequence, expected in (
            ("", "sequence 'imported': has no ground truth to start from: give init = "),
            ('init = "nowhere.npz"', "sequence 'imported' init: file not found"),
            ('init = "ref.trc"', "first poses (init)"),
            ('init = "init.npz"\nreference = "short.trc"', "short.trc: a TRC file has 5 header lines"),
            ('init = "init.npz"\nreference = "other.trc"', "other.trc: the reference names too few keypoints"),
            ('init = "init.npz"\nreference = "ref.trc"\nreference_offset = 9', "no frames in common"),
            ('reference_offset = 1', "reference_offset applies to a reference"),
            ('init = "init.npz"\nnoise = 3', "noise apply to rendered sequences")):
        path = experiment(folder, sequence, "bad.toml", scale=False)  # refused before the priors are built
        out = folder / "refused"
        assert main(["compare", str(path), "--out", str(out)]) == 2, sequence
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert str(path) in err and expected in err, (sequence, err)
        assert not out.exists()  # nothing left behind


@pytest.fixture(scope="module")
def finished(folder) -> Path:
    """The experiment run on the folder with its start and its reference (the reference's frame 1 is the
    sequence's frame 0): its output folder."""
    path = experiment(folder, 'init = "init.npz"\nreference = "ref.trc"\nreference_offset = 1')
    assert main(["compare", str(path), "--out", str(folder / "out")]) == 0
    return folder / "out"


def test_runs_start_from_init_and_the_tables_say_what_can_be_said_without_truth(folder, finished, capsys):
    import av

    out = finished
    md = (out / "table.md").read_text()
    assert "MPJPE" not in md and "PCK" not in md and "| n/a" not in md  # no marker error, and none pretended
    assert "## Without ground truth: spread between seeds (mm)" in md and "s/frame" in md
    assert "## Distance to the reference reconstruction (mm)" in md and "not the truth" in md
    rows = {line.split("|")[1].strip(): line.split("|")[2].strip() for line in md.splitlines()
            if line.startswith("| ") and "±" in line}
    assert set(rows) == {"zero-velocity", "constant-velocity"}
    results = [json.loads(p.read_text()) for p in sorted((out / "runs").glob("*/result.json"))]
    assert len(results) == 4
    for r in results:
        assert r["run"]["init"] == str(folder / "init.npz") and r["tracked_frames"] == [2, 3]
        estimates = np.load(out / "runs" / r["run"]["key"] / "estimates.npz")
        assert np.allclose(estimates["poses"][:2], np.load(folder / "init.npz")["poses"])  # the given start
        # the distance the tables average is compare-trc's, for the same run and the same reference frames
        scored = compare_to_trc(estimates["markers"], folder / "ref.trc", offset=1)
        assert main(["compare-trc", str(out / "runs" / r["run"]["key"]), str(folder / "ref.trc"),
                     "--offset", "1"]) == 0
        printed = float(capsys.readouterr().out.splitlines()[-1].split()[1])
        assert printed == pytest.approx(scored.mean, abs=0.06) and 0 < scored.mean < 150
    csv = (out / "table.csv").read_text()
    for row in ("zero-velocity", "constant-velocity"):
        means = [compare_to_trc(np.load(out / "runs" / r["run"]["key"] / "estimates.npz")["markers"],
                                folder / "ref.trc", offset=1).mean for r in results if r["run"]["row"] == row]
        assert rows[row].startswith(f"{np.mean(means):.1f} ± ")
        assert f"reference_distance,{row},imported," in csv and f"seed_spread,{row},imported," in csv
    # report.html: the two priors over the sequence's own frames, ranked by their distance to the reference
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "no video" not in page and "from the reference" in page
    videos = re.findall(r'<video [^>]*src="data:video/mp4;base64,([A-Za-z0-9+/=]+)"', page)
    stills = re.findall(r'<img class="still" [^>]*src="data:image/jpeg;base64,([A-Za-z0-9+/=]+)"', page)
    assert len(videos) == 1 and len(stills) == 1
    with av.open(io.BytesIO(base64.b64decode(videos[0]))) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    assert len(frames) == 4 and 20 < np.mean(frames[-1]) < 235
    import cv2

    still = cv2.imdecode(np.frombuffer(base64.b64decode(stills[0]), np.uint8), cv2.IMREAD_COLOR)
    assert still.shape[1] > 900 and 20 < np.mean(still) < 235  # two sides, each a grid of both views


def test_without_a_reference_the_report_shows_the_priors_unranked(folder, finished):
    from tracker.app.compare import compare

    out = folder / "unranked"
    shutil.copytree(finished, out)  # the same runs: a reference is not part of a run, only of its tables
    said = []
    compare(experiment(folder, 'init = "init.npz"', "plain.toml"), out, progress=False, say=said.append)
    assert any("4 finished before (skipped), 0 to run" in s for s in said)
    md = (out / "table.md").read_text()
    assert "spread between seeds" in md and "reference" not in md
    page = (out / "report.html").read_text(encoding="utf-8")
    assert page.count("<video ") == 1 and "Unranked (no ground truth or reference): left zero-velocity" in page
