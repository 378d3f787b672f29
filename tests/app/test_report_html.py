"""compare's report.html: one self-contained page with the tables, the per-frame plot and, per sequence, a video
of the best and the worst prior side by side; rewritten the same from the finished runs."""
import base64
import io
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from tracker.app.compare import compare
from tracker.app.report_html import (BY_REFERENCE, BY_TRUTH, TILE_WIDTH, UNRANKED, crop_box, pick_runs,
                                      representative)

SAMPLE = Path(__file__).resolve().parents[2] / "data_tools" / "samples" / "cmu07"
DATE = re.compile(r'<span class="date">[^<]*</span>')


def write_experiment(folder: Path) -> Path:
    """Two rendered sequences (the shipped walk, and the same walk turned), two priors, one seed."""
    text = f'''description = "tiny <report> & videos"
seed = 5
seeds = 1

[tracking]
particles = 30
frames = 5

[[sequence]]
name = "walk"
mocap = "{SAMPLE / '07_02.amc'}"
frames = 6
[[sequence]]
name = "walk turned"
mocap = "{SAMPLE / '07_02.amc'}"
frames = 6
turn = 90

[[prior]]
name = "zero-velocity"
[[prior]]
name = "constant-velocity"
'''
    path = folder / "exp.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished tiny experiment: (experiment file, output folder, what compare said)."""
    folder = tmp_path_factory.mktemp("report")
    path = write_experiment(folder)
    said = []
    compare(path, folder / "out", say=said.append, progress=False)
    return path, folder / "out", said


def videos_of(page: str) -> list[bytes]:
    return [base64.b64decode(v) for v in re.findall(r'<video [^>]*src="data:video/mp4;base64,([A-Za-z0-9+/=]+)"',
                                                   page)]


@pytest.mark.slow
def test_the_page_is_one_file_with_every_table_and_a_video_per_sequence(finished):
    import av

    path, out, said = finished
    page = (out / "report.html").read_text(encoding="utf-8")
    assert not list(out.glob(".*")) and not list(out.glob("videos/.*"))  # no temporary files left
    assert len(list(out.glob("videos/*.mp4"))) == 2  # the videos' cache, which a rerun reuses
    # Nothing is fetched: every src is a data URI, every link a place in the page.
    refs = re.findall(r'\b(src|href)="([^"]*)"', page)
    assert refs and all(v.startswith("data:") for k, v in refs if k == "src")
    assert all(v.startswith("#") for k, v in refs if k == "href")
    assert "http://" not in page and "https://" not in page
    ids = set(re.findall(r'\bid="([^"]+)"', page))
    assert {v[1:] for k, v in refs if k == "href"} <= ids  # every link lands
    # Every table of table.md, under its own heading, linked from the contents, each row there.
    md = (out / "table.md").read_text()
    titles = [line[3:] for line in md.splitlines() if line.startswith("## ")]
    assert len(titles) >= 5
    for title in titles:
        anchor = re.search(rf'<h2 id="([^"]+)">{re.escape(title)}</h2>', page)
        assert anchor and f'href="#{anchor.group(1)}"' in page, title
    assert page.count("<table>") == len(titles)
    for row in ("zero-velocity", "constant-velocity"):
        assert f"<td>{row}</td>" in page
    assert re.search(r'<img [^>]*src="data:image/png;base64,', page)
    assert "tiny &lt;report&gt; &amp; videos" in page  # the description, escaped
    import tracker

    assert f"pose-tracker {tracker.__version__}" in page and str(path) in page
    assert f"python -m tracker compare {path} --out {out}" in page
    # One video per sequence (one variant: a single view set), each an H.264 MP4 that decodes.
    assert [h for h in re.findall(r"<h3 [^>]*>([^<]+)</h3>", page)] == ["walk", "walk turned"]
    videos = videos_of(page)
    assert len(videos) == 2
    for data in videos:
        with av.open(io.BytesIO(data)) as container:
            assert container.format.name.startswith("mov,mp4")
            stream = container.streams.video[0]
            assert stream.codec_context.name == "h264"
            frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
        assert len(frames) == 5 and frames[0].shape[1] == 2 * TILE_WIDTH + 4  # the 5 tracked frames
        assert 20 < np.mean(frames[3]) < 235  # a picture, not a blank
    assert any(s.startswith("report.html: 2 video(s)") for s in said)


@pytest.mark.slow
def test_a_rerun_over_the_finished_folder_writes_the_same_page(finished):
    path, out, _ = finished
    before = (out / "report.html").read_text(encoding="utf-8")
    inode = (out / "report.html").stat().st_ino
    said = []
    compare(path, out, say=said.append, progress=False)
    assert any("4 finished before (skipped), 0 to run" in s for s in said)
    after = (out / "report.html").read_text(encoding="utf-8")
    assert (out / "report.html").stat().st_ino != inode  # written anew (atomically: a new file renamed in place)
    assert DATE.search(after) and DATE.sub("", after) == DATE.sub("", before)


@pytest.mark.slow
def test_no_videos_leaves_them_out_and_a_moved_sequence_is_a_note(finished, tmp_path):
    path, out, _ = finished
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    compare(path, copy, say=lambda s: None, progress=False, videos=False)
    page = (copy / "report.html").read_text(encoding="utf-8")
    assert "<video" not in page and "--no-videos" in page and "<table>" in page
    # A report written from runs whose sequence folder is gone keeps its tables and says why a video is missing.
    from tracker.app.experiment import load_experiment
    from tracker.app.report import write_report
    from tracker.app.report_html import write_html_report

    results = [json.loads((d / "result.json").read_text()) for d in sorted((copy / "runs").iterdir())]
    for r in results:
        r["run"]["sequence_path"] = str(tmp_path / "moved away")
    said = []
    meta = json.loads((copy / "experiment.json").read_text())
    exp = load_experiment(path)
    tables = write_report(exp, results, copy, meta)["report"]
    summary = write_html_report(exp, results, copy, tables, meta, "python -m tracker compare exp.toml --out out",
                                say=said.append)
    page = (copy / "report.html").read_text(encoding="utf-8")
    assert summary["videos"] == 0 and "<video" not in page and "<table>" in page
    assert page.count("no video (") == 2 and "moved away" in page
    assert len([s for s in said if "no video" in s]) == 2


def result(sequence: str, row: str, seed: int, error: float, views=(0, 1), truth: bool = True) -> dict:
    """A run's ``result.json`` content as the report reads it: its per-frame marker error and its settings."""
    from tracker.app.report import PRIMARY

    errors = [error - 1.0, error, error + 1.0] if truth else None
    return {"metrics": {PRIMARY: {"per_frame": errors}}, "tracked_frames": [2, 3, 4],
            "run": {"sequence": sequence, "row": row, "seed_index": seed, "key": f"{sequence}{row}{seed}",
                    "views": list(views), "likelihood": "edge-silhouette", "likelihood_options": {},
                    "particles": 100, "annealing_layers": 3}}


def test_best_and_worst_rows_per_sequence_and_view_set_each_shown_by_its_most_typical_seed():
    results = []
    for seq, offset in (("a", 0.0), ("b", 100.0)):
        for views, shift in (((0, 1), 0.0), ((0,), 50.0)):
            name = "" if len(views) == 2 else ", views 0"
            for row, errors in (("zv", (30, 40, 80)), ("crbm", (10, 22, 30)), ("mix", (40, 45, 50))):
                results += [result(seq, row + name, i, e + offset + shift, views) for i, e in enumerate(errors)]
    results += [result("c", row, i, 20.0, truth=False) for row in ("zv", "crbm", "mix") for i in (1, 0)]
    results += [result("d", "zv", 0, 20.0)]
    # without ground truth, ranked by the distance to the reference: crbm is the nearest, zv the farthest
    for row, distances in (("zv", (90, 70)), ("crbm", (40, 44)), ("mix", (60, 61))):
        for i, d in enumerate(distances):
            results.append(result("e", row, i, 0.0, truth=False))
            results[-1]["reference"] = {"mean": d, "per_frame": [d - 1.0, d + 1.0], "frames": [0, 1]}
    picks, notes = pick_runs(results)
    assert [(p.sequence, p.variant, p.best.row, p.worst.row, p.basis) for p in picks] == [
        ("a", "views 0,1", "crbm", "zv", BY_TRUTH), ("a", "views 0", "crbm, views 0", "zv, views 0", BY_TRUTH),
        ("b", "views 0,1", "crbm", "zv", BY_TRUTH), ("b", "views 0", "crbm, views 0", "zv, views 0", BY_TRUTH),
        ("c", "views 0,1", "zv", "crbm", UNRANKED), ("e", "views 0,1", "crbm", "zv", BY_REFERENCE)]
    first = picks[0]
    assert first.best.mean_mm == pytest.approx(62 / 3) and first.worst.mean_mm == pytest.approx(50.0)
    # zv's mean is 50: seed 1 (40) is the closest; crbm's is 20.67: seed 1 (22)
    assert first.worst.run["run"]["seed_index"] == 1 and first.best.run["run"]["seed_index"] == 1
    unranked, referenced = picks[4], picks[5]
    assert np.isnan(unranked.best.mean_mm) and unranked.best.run["run"]["seed_index"] == 0  # the lowest seed
    assert referenced.best.mean_mm == pytest.approx(42.0) and referenced.worst.mean_mm == pytest.approx(80.0)
    assert referenced.best.run["run"]["seed_index"] == 0 and referenced.best.run_mm == pytest.approx(40.0)
    assert notes == ["c (views 0,1): the first two of 3 rows shown (no ground truth or reference to rank the "
                     "priors by)", "d (views 0,1): no video (one prior only)"]
    tie = [result("a", "zv", 0, 10.0), result("a", "zv", 1, 30.0)]
    assert representative(tie)["run"]["seed_index"] == 0  # equally close: the lower seed index


def test_crop_box_holds_every_outline_point_within_the_image():
    rng = np.random.default_rng(3)
    for _ in range(200):
        centre = rng.uniform([0, 0], [640, 480])
        points = [centre + rng.normal(0, rng.uniform(5, 150), (20, 2)) for _ in range(3)]
        x0, y0, x1, y1 = crop_box(points, 640, 480)
        assert 0 <= x0 < x1 <= 640 and 0 <= y0 < y1 <= 480
        w, h = x1 - x0, y1 - y0
        assert w >= min(160, 640) - 1 and w >= 0.9 * h - 1 or w == 640
        inside = np.concatenate(points)
        inside = inside[(inside[:, 0] >= 0) & (inside[:, 0] <= 639) & (inside[:, 1] >= 0) & (inside[:, 1] <= 479)]
        if len(inside):
            assert np.all(inside >= [x0 - 1, y0 - 1]) and np.all(inside <= [x1, y1])
    assert crop_box([np.array([[-50.0, -20.0]])], 640, 480) == (0, 0, 640, 480)


def test_no_videos_flag():
    from tracker.app.parser import build_parser

    argv = ["compare", "exp.toml", "--out", "o"]
    assert build_parser(argv).parse_args(argv).videos is True
    assert build_parser(argv).parse_args(argv + ["--no-videos"]).videos is False
