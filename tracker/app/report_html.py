"""``report.html``: an experiment's tables, per-frame plot and overlay videos in one self-contained page.

The page holds everything it shows (the per-frame plot as a PNG and the videos as H.264 MP4, both as base64
``data:`` URIs, the style inline), so the one file opens in any browser, offline, wherever it is copied. It is
built from the finished runs alone (their ``result.json`` and ``estimates.npz``, and the sequence folders),
so running ``compare`` again over a finished folder writes the same page again, apart from its date; the
videos are also kept in ``OUT/videos/`` (by a hash of what they show) and reused by such a rerun. The tables
come as data (:class:`tracker.app.report_tables.Report`, the same that ``table.md`` is written from), shown by
:func:`tables_html` with the best mean of each column and the paired differences that exclude zero coloured.

For every sequence and every variant of the grid (view set, likelihood, particle count, annealing layers:
rows that differ only in their prior) one video puts the best and the worst prior side by side: the rows with
the lowest and the highest marker error (mean over seeds). Each side shows the run whose own mean error is the
closest to its row's mean over seeds (the lowest seed index on a tie): its estimate (the mean pose, drawn like
``track --video``) and the ground truth over the first camera of the view set, at most
:data:`VIDEO_FRAMES` frames (every k-th frame of a longer sequence), :data:`TILE_WIDTH` pixels wide per side;
under it a still of the last frame in every view of the view set, each side's estimate over the frames.

A sequence without ground truth (an imported video) ranks its rows by their distance to the reference
reconstruction the experiment names for it (:mod:`data_tools.sequences.reference`), and without one shows its first two
rows, unranked, over its own frames.
"""
from __future__ import annotations

import base64
import logging
import html
import math
import re
import shlex
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from string import Template
from typing import Callable, Iterator

import numpy as np

from data_tools.io.files import write_text_atomic
from tracker.app.report_tables import Code, Report, Table, Text, cell_marks
from tracker.core.errors import InputError

log = logging.getLogger(__name__)

#: Most frames in a video (a longer sequence shows every k-th frame).
VIDEO_FRAMES = 150
#: Width of each side of a video (pixels).
TILE_WIDTH = 320
#: x264's constant rate factor for the videos (20 is ``track --video``'s; higher is smaller).
VIDEO_CRF = 26
#: Width of each side's grid of views in a still (pixels), and its JPEG quality.
STILL_WIDTH = 480
STILL_QUALITY = 85
#: What ranks a video's rows (:attr:`Side.basis`): the marker error against the ground truth, the distance to a
#: reference reconstruction, or nothing (a sequence with neither: its first two rows, unranked).
BY_TRUTH, BY_REFERENCE, UNRANKED = "marker error", "distance to the reference", ""


# -- choosing the runs shown --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Side:
    """One side of a comparison video: a table row, its mean score over seeds (mm: the marker error, or the
    distance to the reference, as ``basis`` says; nan when unranked), how many seeds, and the run shown (its
    ``result.json`` with ``run``)."""

    row: str
    mean_mm: float
    seeds: int
    run: dict
    basis: str = BY_TRUTH

    @property
    def run_mm(self) -> float:
        return run_score(self.run, self.basis)


@dataclass(frozen=True)
class Pick:
    """The best and the worst prior of one sequence and grid variant (``variant``: the settings the two share
    that vary in the experiment, e.g. ``"views 0"``; empty when the grid has one variant)."""

    sequence: str
    variant: str
    best: Side
    worst: Side

    @property
    def basis(self) -> str:
        """What ranked the two rows (:data:`BY_TRUTH`, :data:`BY_REFERENCE` or :data:`UNRANKED`)."""
        return self.best.basis


def _variant_key(run: dict) -> tuple:
    """Everything but the prior that tells a run's table row apart."""
    views = None if run["views"] is None else tuple(run["views"])
    return (run["likelihood"], repr(sorted(run["likelihood_options"].items())), views, run["particles"],
            run["annealing_layers"])


def _variant_names(keys: list[tuple]) -> dict[tuple, str]:
    """Each variant described by the settings that differ between the variants (none: an empty name)."""
    def parts(key: tuple) -> list[str]:
        likelihood, options, views, particles, layers = key
        return [f"likelihood {likelihood}" + ("" if options == "[]" else f" {options}"),
                "all views" if views is None else f"views {','.join(map(str, views))}",
                f"{particles} particles", f"{layers} annealing layer{'s' if layers != 1 else ''}"]

    described = [parts(k) for k in keys]
    varying = [i for i in range(4) if len({d[i] for d in described}) > 1]
    return {k: ", ".join(d[i] for i in varying) for k, d in zip(keys, described)}


def marker_errors(result: dict) -> list[float] | None:
    """A run's per-frame marker error (mm; the tables' first metric) from its ``result.json`` content, or None
    without ground truth."""
    from tracker.app.report import PRIMARY, per_frame_values

    return per_frame_values(result, PRIMARY)


def per_frame_scores(result: dict, basis: str) -> dict[int, float]:
    """A run's score per frame (mm) by ``basis``: frame -> marker error (its tracked frames) or distance to the
    reference (every frame compared); empty when unranked."""
    from tracker.app.report import reference_values

    if basis == BY_TRUTH:
        return dict(zip(result["tracked_frames"], marker_errors(result)))
    if basis == BY_REFERENCE:
        return dict(zip(result["reference"]["frames"], reference_values(result)))
    return {}


def run_score(result: dict, basis: str = BY_TRUTH) -> float:
    """A run's mean score over its frames (mm) by ``basis`` (:func:`per_frame_scores`); nan when unranked."""
    values = list(per_frame_scores(result, basis).values())
    return float(np.mean(values)) if values else float("nan")


def representative(runs: list[dict], basis: str = BY_TRUTH) -> dict:
    """The run whose mean score (:func:`run_score`) is the closest to the mean over ``runs`` (the lowest seed
    index on a tie, and when unranked)."""
    if basis == UNRANKED:
        return min(runs, key=lambda r: r["run"]["seed_index"])
    means = np.array([run_score(r, basis) for r in runs])
    order = sorted(range(len(runs)), key=lambda i: (abs(means[i] - means.mean()), runs[i]["run"]["seed_index"]))
    return runs[order[0]]


def _basis(runs: list[dict]) -> str:
    """What can rank ``runs``: their marker error where every one has it, else their distance to the reference."""
    from tracker.app.report import reference_values

    if all(marker_errors(r) for r in runs):
        return BY_TRUTH
    if all(reference_values(r) for r in runs):
        return BY_REFERENCE
    return UNRANKED


def pick_runs(results: list[dict]) -> tuple[list[Pick], list[str]]:
    """The best and the worst row of every sequence and grid variant (by the mean over seeds of each run's mean
    marker error; without ground truth, its mean distance to the reference; with neither, the first two rows,
    unranked), each with its :func:`representative` run; and a note for each sequence and variant that has a
    single prior (no video) or more than two unranked rows (the first two shown)."""
    groups: dict[tuple[str, tuple], dict[str, list[dict]]] = {}
    for r in results:
        groups.setdefault((r["run"]["sequence"], _variant_key(r["run"])), {}).setdefault(r["run"]["row"], []).append(r)
    names = _variant_names(list(dict.fromkeys(k for _, k in groups)))
    picks, notes = [], []
    for (sequence, key), rows in groups.items():
        where = sequence + (f" ({names[key]})" if names[key] else "")
        if len(rows) < 2:
            notes.append(f"{where}: no video (one prior only)")
            continue
        basis = _basis([r for runs in rows.values() for r in runs])
        if basis == UNRANKED:
            first, second = (Side(row, float("nan"), len(runs), representative(runs, basis), basis)
                             for row, runs in list(rows.items())[:2])
            picks.append(Pick(sequence, names[key], first, second))
            if len(rows) > 2:
                notes.append(f"{where}: the first two of {len(rows)} rows shown (no ground truth or reference "
                             "to rank the priors by)")
            continue
        sides = [Side(row, float(np.mean([run_score(r, basis) for r in runs])), len(runs),
                      representative(runs, basis), basis) for row, runs in rows.items()]
        best = min(sides, key=lambda s: s.mean_mm)
        worst = max(sides, key=lambda s: s.mean_mm)
        if best.row == worst.row:  # every row equally good
            worst = next(s for s in sides if s.row != best.row)
        picks.append(Pick(sequence, names[key], best, worst))
    return picks, notes


# -- the videos ---------------------------------------------------------------------------------------------------

def _short_label(row: str, labels: list[str]) -> str:
    """A row's prior label (the row without the variant that both sides share)."""
    from tracker.app.report import split_row_label

    return split_row_label(row, labels)[0]


def crop_box(polygons: list[np.ndarray], width: int, height: int, margin: float = 0.15, min_width: int = 160
             ) -> tuple[int, int, int, int]:
    """The part of a ``width x height`` image that a video shows: the box (x0, y0, x1, y1), pixels, around
    every outline point inside the image (``polygons``: ``n x 2`` arrays), widened by ``margin`` of its size on
    each side, at least ``min_width`` wide (so that small figures are not enlarged more than
    ``TILE_WIDTH / min_width`` times), at least 0.9 times as wide as tall and at most twice as wide as tall,
    within the image (the whole image when no point is inside)."""
    pts = np.concatenate([p for p in polygons if p is not None and len(p)] or [np.zeros((0, 2))])
    pts = pts[(pts[:, 0] >= 0) & (pts[:, 0] <= width - 1) & (pts[:, 1] >= 0) & (pts[:, 1] <= height - 1)]
    if not len(pts):
        return 0, 0, width, height
    (x0, y0), (x1, y1) = pts.min(axis=0), pts.max(axis=0)
    pad = margin * max(x1 - x0, y1 - y0)
    w, h = x1 - x0 + 2 * pad, y1 - y0 + 2 * pad
    w = min(max(w, 0.9 * h, min_width), width)
    h = min(max(h, w / 2), height)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    left = int(round(min(max(cx - w / 2, 0), width - w)))
    top = int(round(min(max(cy - h / 2, 0), height - h)))
    return left, top, left + int(round(w)), top + int(round(h))


def comparison_frames(pick: Pick, seq, runs_dir: Path, labels: list[str]) -> tuple[Iterator[np.ndarray], int, int]:
    """The frames of ``pick``'s video (RGB, made as they are iterated), how many, and the step between shown
    sequence frames: a legend, then side by side for each prior its name and errors above the camera's image
    (cut to the part where the figure and the estimates are, :func:`crop_box`) with its estimate, the ground
    truth where there is one and the frame's score (marker error, or distance to the reference)."""
    sides = _sides(pick)
    views = pick.best.run["run"]["views"]
    view = 0 if views is None else views[0]
    poses = _poses(pick, seq, runs_dir)
    n = min(seq.n_frames, *(len(p) for p in poses))
    step = max(1, math.ceil(n / VIDEO_FRAMES))
    shown = list(range(0, n, step))
    headers = [[f"{which}: {_short_label(s.row, labels)}", _score_line(s)] for which, s in sides]
    errors = [per_frame_scores(s.run, s.basis) for _, s in sides]
    first = [s.run.get("first_tracked_frame", 0) for _, s in sides]
    return _frames(seq, view, poses, shown, headers, errors, first), len(shown), step


def _sides(pick: Pick) -> list[tuple[str, Side]]:
    """The two sides with their headings: best and worst, or left and right when unranked."""
    names = ("left", "right") if pick.basis == UNRANKED else ("best", "worst")
    return list(zip(names, (pick.best, pick.worst)))


def _poses(pick: Pick, seq, runs_dir: Path) -> list[np.ndarray]:
    """The estimated poses ``T x D`` of the two runs shown."""
    from data_tools.sequences.estimates import read_poses_file

    return [read_poses_file(runs_dir / s.run["run"]["key"] / "estimates.npz", "estimates", seq.model)
            for s in (pick.best, pick.worst)]


def _score_line(side: Side) -> str:
    """A side's score, over its seeds and of the seed shown, as its header says it."""
    seed = side.run["run"]["seed_index"]
    if side.basis == UNRANKED:
        return f"{side.seeds} seed(s); seed {seed} shown"
    what = "" if side.basis == BY_TRUTH else " to the reference"
    return f"{side.mean_mm:.0f} mm{what} over {side.seeds} seed(s); seed {seed}: {side.run_mm:.0f} mm"


def _frame_text(k: int, scores: dict[int, float], first: int) -> str:
    """A tile's caption: the frame, its score (mm) and whether its pose was given."""
    parts = [f"{scores[k]:.0f} mm"] if k in scores else []
    if k < first:
        parts.append("given")
    return f"frame {k}" + (": " + ", ".join(parts) if parts else "")


def _frames(seq, view: int, poses: list[np.ndarray], shown: list[int], headers: list[list[str]],
            errors: list[dict[int, float]], first: list[int]) -> Iterator[np.ndarray]:
    """:func:`comparison_frames`' pictures."""
    import cv2

    from tracker.app.visualize import (draw_estimate_and_truth, label, legend_strip, scale_polygons,
                                       segment_polygons, side_by_side, text_strip)

    rig = seq.rig.subset([view])
    cam = rig[0]
    truth = None if seq.groundtruth is None else seq.groundtruth.poses
    outlines = {k: ([segment_polygons(seq.model, p[k], rig)[0] for p in poses],
                    segment_polygons(seq.model, truth[k], rig)[0] if truth is not None and k < len(truth) else None)
                for k in shown}
    x0, y0, x1, y1 = crop_box([q for est, gt in outlines.values() for polys in [*est, gt or []] for q in polys
                               if q is not None], cam.width, cam.height)
    scale = TILE_WIDTH / (x1 - x0)
    size = (TILE_WIDTH, int(round((y1 - y0) * scale)))
    heads = [text_strip(TILE_WIDTH, lines) for lines in headers]
    legend = legend_strip(2 * TILE_WIDTH + 4, "estimate", truth is not None, cam.name)
    for k in shown:
        image = cv2.resize(seq.image(k, view)[y0:y1, x0:x1], size, interpolation=cv2.INTER_AREA)
        est, gt = outlines[k]
        gt = None if gt is None else scale_polygons(gt, scale, (x0, y0))
        tiles = []
        for polys, err, head, known in zip(est, errors, heads, first):
            tile = draw_estimate_and_truth(image, seq.model, scale_polygons(polys, scale, (x0, y0)), gt, 2)
            tile = label(tile, _frame_text(k, err, known), (4, 4), 0.45)
            tiles.append(np.concatenate([head, tile]))
        yield np.concatenate([legend, side_by_side(tiles)])


def render_video(pick: Pick, seq, runs_dir: Path, labels: list[str], fps: float, cache: Path
                 ) -> tuple[bytes, int, int]:
    """``pick``'s video as MP4 bytes (H.264), its frame count and its frame step. The video is kept in the
    folder ``cache`` under a hash of everything that determines its pictures (the two runs, their captions, the
    video settings, the package version) and reused from there: x264 does not always encode the same frames
    into the same bytes, and a rerun is to write the same page."""
    import tracker
    from data_tools.io.fingerprints import config_hash
    from tracker.app.visualize import write_video

    frames, count, step = comparison_frames(pick, seq, runs_dir, labels)
    ident = {"runs": [pick.best.run["run"]["key"], pick.worst.run["run"]["key"]],
             "captions": [[_short_label(s.row, labels), _score_line(s), s.seeds] for s in (pick.best, pick.worst)],
             "scores": [{str(k): round(v, 3) for k, v in per_frame_scores(s.run, s.basis).items()}
                        for s in (pick.best, pick.worst)],
             "video": [TILE_WIDTH, VIDEO_FRAMES, VIDEO_CRF, float(fps)], "version": tracker.__version__}
    path = cache / f"{config_hash(ident)}.mp4"
    if not path.exists():
        write_video(path, frames, fps, crf=VIDEO_CRF)  # atomically: an interrupted one is not kept
    return path.read_bytes(), count, step


def still_image(pick: Pick, seq, runs_dir: Path, labels: list[str]) -> tuple[bytes, int]:
    """A still of ``pick``'s last frame in every view of its view set, the two sides' estimates (over the ground
    truth where there is one) next to each other, :data:`STILL_WIDTH` pixels wide each: JPEG bytes and the
    frame shown."""
    import cv2

    from tracker.app.visualize import overlay_grid, side_by_side, text_strip

    views = pick.best.run["run"]["views"]
    views = list(range(seq.n_views)) if views is None else list(views)
    poses = _poses(pick, seq, runs_dir)
    k = min(seq.n_frames, *(len(p) for p in poses)) - 1
    truth = seq.groundtruth.poses[k] if seq.groundtruth is not None and k < len(seq.groundtruth.poses) else None
    tiles = []
    for (which, side), pose in zip(_sides(pick), poses):
        picture = overlay_grid(seq, pose[k], k, views, f"frame {k}", thickness=2, truth=truth,
                               estimate_name="estimate")
        height = int(round(picture.shape[0] * STILL_WIDTH / picture.shape[1]))
        picture = cv2.resize(picture, (STILL_WIDTH, height), interpolation=cv2.INTER_AREA)
        head = text_strip(STILL_WIDTH, [f"{which}: {_short_label(side.row, labels)}", _score_line(side)])
        tiles.append(np.concatenate([head, picture]))
    ok, data = cv2.imencode(".jpg", cv2.cvtColor(side_by_side(tiles), cv2.COLOR_RGB2BGR),
                            [cv2.IMWRITE_JPEG_QUALITY, STILL_QUALITY])
    if not ok:  # pragma: no cover - OpenCV encodes any RGB array
        raise InputError("cannot encode the still as JPEG")
    return data.tobytes(), k


# -- the page -----------------------------------------------------------------------------------------------------

def compare_command(experiment: str | Path, out: str | Path, jobs: int = 1, backend: str = "joblib",
                    address: str | None = None, data_root: str | Path | None = None, videos: bool = True) -> str:
    """The ``compare`` command line that writes this output folder."""
    args = ["python", "-m", "tracker", "compare", str(experiment), "--out", str(out)]
    if jobs != 1:
        args += ["--jobs", str(jobs)]
    if backend != "joblib":
        args += ["--backend", backend]
    if address:
        args += ["--address", address]
    if data_root is not None:
        args += ["--data-root", str(data_root)]
    if not videos:
        args.append("--no-videos")
    return shlex.join(args)


def tables_html(report: Report, taken: set[str]) -> tuple[str, str, list[tuple[str, str]]]:
    """``report``'s tables (:mod:`tracker.app.report_tables`, as :func:`tracker.app.report.write_report` builds
    them) as HTML: the introduction's paragraphs, every table under its own heading with its notes above it, and
    each table's (anchor, title) for the contents; the anchors are added to ``taken``."""
    intro = "".join(f"<p>{_text_html(t)}</p>\n" for t in report.intro)
    blocks, links = [], []
    for table in report.tables:
        anchor = _slug(table.title, taken)
        links.append((anchor, table.title))
        block = [f'<h2 id="{anchor}">{html.escape(table.title)}</h2>']
        block += [f'<p class="note">{_text_html(t)}</p>' for t in table.notes]
        block.append(_table_html(table))
        blocks.append("\n".join(block))
    return intro, "\n".join(blocks), links


def _text_html(text: Text) -> str:
    """A line of text as HTML: escaped, its :class:`~tracker.app.report_tables.Code` parts in ``<code>``."""
    return "".join(f"<code>{html.escape(part.text)}</code>" if isinstance(part, Code) else html.escape(part)
                   for part in text)


def _table_html(table: Table) -> str:
    """One table, scrolling sideways when wider than the page; each body cell carries its mark
    (:func:`~tracker.app.report_tables.cell_marks`) as its CSS class: ``best``, ``better`` or ``worse``."""
    marks = cell_marks(table)
    head = "".join(f"<th>{html.escape(h)}</th>" for h in table.header)
    body = "".join("<tr>" + "".join(f'<td class="{mark}">{html.escape(cell.text)}</td>' if mark else
                                    f"<td>{html.escape(cell.text)}</td>" for cell, mark in zip(row, row_marks))
                   + "</tr>\n" for row, row_marks in zip(table.rows, marks))
    return f'<div class="scroll"><table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}</tbody></table></div>'


def _slug(text: str, taken: set[str]) -> str:
    base = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")[:48] or "section"
    slug, i = base, 2
    while slug in taken:
        slug, i = f"{base}-{i}", i + 1
    taken.add(slug)
    return slug


def _data_uri(kind: str, data: bytes) -> str:
    return f"data:{kind};base64,{base64.b64encode(data).decode('ascii')}"


PAGE = Template("""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>$title</title>
<style>
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 0 auto; max-width: 1320px;
       padding: 0 24px 48px; color: #1d2329; line-height: 1.45; }
h1 { margin: 28px 0 4px; font-size: 1.7em; }
h2 { margin-top: 40px; padding-top: 8px; border-top: 1px solid #dde2e7; font-size: 1.25em; }
h3 { margin: 24px 0 8px; font-size: 1.05em; }
.description { color: #47525d; max-width: 980px; }
dl.meta { display: grid; grid-template-columns: max-content 1fr; gap: 2px 16px; margin: 16px 0; font-size: 0.92em; }
dl.meta dt { color: #5d6873; }
dl.meta dd { margin: 0; }
code { font-family: ui-monospace, "SFMono-Regular", Menlo, Consolas, monospace; font-size: 0.9em;
       background: #f1f3f5; padding: 1px 4px; border-radius: 3px; word-break: break-all; }
nav { background: #f6f8fa; border: 1px solid #dde2e7; border-radius: 6px; padding: 10px 16px; margin: 16px 0; }
nav ul { margin: 4px 0 0; padding-left: 20px; columns: 2; column-gap: 32px; }
nav li { margin: 2px 0; }
a { color: #0b5cad; text-decoration: none; }
a:hover { text-decoration: underline; }
.scroll { overflow-x: auto; }
table { border-collapse: collapse; font-size: 0.9em; margin: 8px 0; }
th, td { border: 1px solid #dde2e7; padding: 4px 10px; text-align: right; white-space: nowrap; }
th { background: #f1f3f5; position: sticky; top: 0; }
th:first-child, td:first-child { text-align: left; white-space: normal; min-width: 14em; }
tbody tr:nth-child(even) { background: #fafbfc; }
td.best { font-weight: 700; background: #e3f4e6; }
td.better { background: #e3f4e6; }
td.worse { background: #fbe5e3; }
.note { color: #5d6873; font-size: 0.9em; }
img.plot, img.still { max-width: 100%; height: auto; border: 1px solid #dde2e7; }
figure { margin: 12px 0 28px; }
figcaption { color: #47525d; font-size: 0.9em; margin-top: 4px; max-width: 980px; }
video { display: block; max-width: 100%; height: auto; background: #000; }
</style>
</head>
<body>
<h1>$title</h1>
<p class="description">$description</p>
<dl class="meta">
<dt>experiment file</dt><dd><code>$experiment</code></dd>
<dt>package version</dt><dd>pose-tracker $version</dd>
<dt>written</dt><dd><span class="date">$date</span></dd>
<dt>command</dt><dd><code>$command</code></dd>
<dt>runs</dt><dd>$runs</dd>
</dl>
<nav><strong>Contents</strong>
<ul>
$contents
</ul>
</nav>
$intro
$tables
<h2 id="per-frame">Error per frame</h2>
<p class="note">Each line is a row's mean over its runs with a band of &plusmn;1 standard deviation; one panel per
sequence (<code>per_frame.png</code>); a sequence without ground truth shows the distance to its reference
reconstruction instead, where it has one.</p>
<img class="plot" alt="error per frame of every row" src="$plot">
<h2 id="videos">Best and worst prior, side by side</h2>
$videos
</body>
</html>
""")


def _videos_html(exp, results: list[dict], runs_dir: Path, taken: set[str], say: Callable[[str], None]
                 ) -> tuple[str, list[tuple[str, str]], int]:
    """The videos' section (:func:`pick_runs`, :func:`render_video`), the (anchor, title) of each video and
    how many were made."""
    from tracker.app.api import load_sequence

    picks, notes = pick_runs(results)
    labels = [p.label for p in exp.priors]
    parts = [f"<p class=\"note\">For every sequence{' and grid variant' if any(p.variant for p in picks) else ''}: "
             "the rows with the lowest (left) and the highest (right) marker error (the first table's metric), "
             "mean over seeds. Each side shows one run, the seed whose own mean error is the closest to its row's "
             "mean over seeds: its estimate (the mean pose; left segments red, right light blue, centre yellow) "
             "with the ground truth in green, over the first camera of the view set, "
             f"{TILE_WIDTH} px wide per side; under it, the last frame in every view of the view set. A sequence "
             "without ground truth ranks its rows by their distance to its reference reconstruction (which is "
             "another method's estimate, not the truth) or, without one, shows its first two rows unranked (the "
             "lowest seed index of each).</p>"]
    links, sequences, made = [], {}, 0
    for pick in picks:
        title = pick.sequence + (f": {pick.variant}" if pick.variant else "")
        anchor = _slug(f"video {title}", taken)
        links.append((anchor, f"video: {title}"))
        parts.append(f'<h3 id="{anchor}">{html.escape(title)}</h3>')
        try:
            if pick.sequence not in sequences:
                sequences[pick.sequence] = load_sequence(pick.best.run["run"]["sequence_path"])
            seq = sequences[pick.sequence]
            data, count, step = render_video(pick, seq, runs_dir, labels, seq.fps or exp.fps,
                                             runs_dir.parent / "videos")
            still, still_frame = still_image(pick, seq, runs_dir, labels)
        except InputError as exc:
            note = f"{title}: no video ({exc})"
            say(f"report.html: {note}")
            parts.append(f'<p class="note">{html.escape(note)}</p>')
            continue
        made += 1
        shown = f"{count} frames" + (f", one sequence frame in {step} ({step}× speed)" if step > 1 else "")
        best, worst = pick.best, pick.worst
        if pick.basis == UNRANKED:
            said = (f"Unranked (no ground truth or reference): left {html.escape(best.row)}, "
                    f"right {html.escape(worst.row)} (seeds {best.run['run']['seed_index']} and "
                    f"{worst.run['run']['seed_index']} shown).")
        else:
            what = "" if pick.basis == BY_TRUTH else " from the reference"
            said = (f"Best: {html.escape(best.row)}, {best.mean_mm:.1f} mm{what} "
                    f"(seed {best.run['run']['seed_index']} shown, {best.run_mm:.1f} mm). "
                    f"Worst: {html.escape(worst.row)}, {worst.mean_mm:.1f} mm{what} "
                    f"(seed {worst.run['run']['seed_index']} shown, {worst.run_mm:.1f} mm).")
        parts.append(
            f'<figure>\n<video controls loop muted autoplay playsinline src="{_data_uri("video/mp4", data)}">'
            f"</video>\n<figcaption>{said} {shown}, {len(data) // 1024} KB.</figcaption>\n</figure>")
        parts.append(
            f'<figure>\n<img class="still" alt="the estimates of frame {still_frame} in every view" '
            f'src="{_data_uri("image/jpeg", still)}">\n<figcaption>Frame {still_frame}, the last, in every view of '
            "the view set: each side's estimate over the camera images.</figcaption>\n</figure>")
    parts += [f'<p class="note">{html.escape(n)}</p>' for n in notes]
    return "\n".join(parts), links, made


def write_html_report(exp, results: list[dict], out: Path, tables: Report, meta: dict, command: str,
                      videos: bool = True, say: Callable[[str], None] | None = None) -> dict:
    """Write ``out/report.html`` (atomically) from the experiment ``exp``, its run ``results`` (each
    ``result.json`` with ``run``; estimates in ``out/runs/<key>/estimates.npz``), its ``tables`` (the
    ``report`` of :func:`tracker.app.report.write_report`, which ``table.md`` shows), ``out/per_frame.png``,
    ``meta`` (``version``, ``runs``) and the ``command`` that wrote them; ``videos=False`` leaves the videos
    out. A video that cannot be made (a sequence folder moved away) is a note on the page, also passed to ``say``
    (default: this module's logger). Returns the number of ``videos`` and the ``video_seconds`` they took."""
    say = say or log.info
    taken = {"per-frame", "videos"}
    intro, tables_part, links = tables_html(tables, taken)
    links += [("per-frame", "Error per frame"), ("videos", "Best and worst prior, side by side")]
    t0 = time.perf_counter()
    made = 0
    if videos:
        video_html, video_links, made = _videos_html(exp, results, out / "runs", taken, say)
        links += video_links
    else:
        video_html = ('<p class="note">Videos left out (<code>--no-videos</code>); run the command without it to '
                      "add them.</p>")
    seconds = time.perf_counter() - t0
    page = PAGE.substitute(
        title=html.escape(exp.path.stem), description=html.escape(exp.description or ""),
        experiment=html.escape(str(exp.path)), version=html.escape(str(meta["version"])),
        date=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), command=html.escape(command),
        runs=html.escape(f"{meta['runs']} ({exp.seeds} seed(s) per configuration, master seed {exp.seed})"),
        contents="\n".join(f'<li><a href="#{a}">{html.escape(t)}</a></li>' for a, t in links), intro=intro,
        tables=tables_part, plot=_data_uri("image/png", (out / "per_frame.png").read_bytes()), videos=video_html)
    write_text_atomic(out / "report.html", page)
    if videos:
        say(f"report.html: {made} video(s) in {seconds:.0f} s")
    return {"videos": made, "video_seconds": seconds}
