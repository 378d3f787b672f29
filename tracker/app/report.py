"""An experiment's tables (Taylor 2009, Table 6.1 layout) and per-frame plot.

For every table row (prior, and likelihood variant / view set / particle count where the grid has several)
and sequence: mean ± standard deviation over seeds of each run's mean over frames, for every metric of
:data:`tracker.core.metrics.METRICS` (MPJPE absolute and root-relative, PA-MPJPE, 3DPCK at 150 mm absolute and
root-relative; the names and formulas are there) and seconds per frame. The paired differences table gives, for
every row against the baseline, the mean over seed indices of (row - baseline) absolute MPJPE with a 95%
percentile bootstrap interval (10,000 resamples of
the seed indices, seeded): runs of the same seed index share their generator's seed, so the pairing removes
common sequence difficulty.

A sequence without ground truth (an imported video) has no marker error: it is left out of those tables and has
its own, with what can be said without one: the seconds per frame, the spread between seeds (how far apart the
runs of different seeds put the markers, :func:`seed_spread`) and, where the experiment names a reference
reconstruction, each run's mean distance to it after one rigid alignment
(:func:`data_tools.sequences.reference.compare_to_reference`, as ``compare-trc`` prints it).

The tables are built once as data (:class:`tracker.app.report_tables.Report`), which :func:`markdown` writes as
``table.md`` and :mod:`tracker.app.report_html` as the tables of ``report.html``.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Callable

import numpy as np

from data_tools.io.files import atomic_path, write_text_atomic
from tracker.app.report_tables import Cell, Code, Report, Table, Text
from tracker.core.metrics import METRICS as CORE_METRICS, summarize_runs

#: The tables' metrics: (name, unit, heading), the names and order of :data:`tracker.core.metrics.METRICS`.
METRICS = tuple((m.name, m.unit, f"{m.name}: {m.title} ({m.unit})") for m in CORE_METRICS)
#: The metric of the paired differences, the replicate table and the plot.
PRIMARY = CORE_METRICS[0].name
#: Where runs finished by earlier versions of this version number kept their per-frame values (``result.json``
#: before ``"metrics"``); a metric they lack shows as n/a.
_EARLIER_KEYS = {"mpjpe_abs": "per_frame_error_mm", "mpjpe_rel": "per_frame_relative_error_mm",
                 "pa_mpjpe": "per_frame_pa_mpjpe_mm", "pck_abs": "per_frame_pck150"}
BOOTSTRAP_DRAWS = 10_000


def bootstrap_interval(differences: np.ndarray, level: float = 0.95, draws: int = BOOTSTRAP_DRAWS,
                       seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean of paired differences ``(n,)``."""
    d = np.asarray(differences, float)
    if len(d) < 2:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    means = d[rng.integers(0, len(d), (draws, len(d)))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def per_frame_values(result: dict, metric: str) -> list[float] | None:
    """A run's per-frame values of ``metric`` (a name of :data:`METRICS`) from its ``result.json`` content, or
    None (no ground truth, or a run written before the metric existed)."""
    metrics = result.get("metrics")
    if isinstance(metrics, dict):
        return (metrics.get(metric) or {}).get("per_frame")
    return result.get(_EARLIER_KEYS.get(metric, ""))


def per_run(result: dict, metric: str) -> float:
    """A run's mean over its tracked frames of ``metric`` (nan where it has none)."""
    v = per_frame_values(result, metric)
    return float(np.mean(v)) if v else float("nan")


def split_row_label(row: str, labels: list[str]) -> tuple[str, str]:
    """(prior label, the rest: likelihood variant, view set, ...) of a table row's label, given the experiment's
    prior ``labels`` (the longest that fits)."""
    label = next((lab for lab in sorted(labels, key=len, reverse=True) if row == lab or row.startswith(lab + ", ")),
                 row)
    return label, row[len(label):]


def has_truth(runs: list[dict]) -> bool:
    """Whether every run of ``runs`` (``result.json`` contents) has a marker error (its sequence ground truth)."""
    return bool(runs) and all(per_frame_values(r, PRIMARY) for r in runs)


def reference_values(result: dict) -> list[float] | None:
    """A run's per-frame distances to its sequence's reference reconstruction (mm), or None without one."""
    return (result.get("reference") or {}).get("per_frame")


def seed_spread(markers: list[np.ndarray]) -> float:
    """How far apart the runs of different seeds put the markers: the mean over frames, markers and runs of each
    run's distance to the mean over runs (mm); ``markers`` one ``T x 15 x 3`` array per run (its tracked frames,
    mm). Nan for fewer than two runs."""
    if len(markers) < 2:
        return float("nan")
    n = min(len(m) for m in markers)
    stack = np.stack([np.asarray(m, float)[:n] for m in markers])  # runs x T x 15 x 3
    return float(np.linalg.norm(stack - stack.mean(axis=0), axis=-1).mean())


def _tracked_markers(result: dict, runs_dir: Path) -> np.ndarray:
    """A run's markers ``T x 15 x 3`` (mm) in its tracked frames, from its ``estimates.npz``."""
    from data_tools.io.checks import load_npz

    markers = load_npz(runs_dir / result["run"]["key"] / "estimates.npz", "estimates", ("markers",))["markers"]
    return markers[result["tracked_frames"]]


def _cell(values: list[float], digits: int = 1) -> Cell:
    """``mean ± std`` over runs (:func:`~tracker.core.metrics.summarize_runs`), ranked by its mean; or n/a."""
    v = np.asarray(values, float)
    if v.size == 0 or not np.all(np.isfinite(v)):
        return Cell("n/a")
    mean, sd = summarize_runs(v)
    return Cell(f"{mean:.{digits}f} ± {sd:.{digits}f}", mean=float(mean), digits=digits)


def _row(*cells: Cell | str) -> tuple[Cell, ...]:
    """A table row: its cells, a plain text (a label, a count, a time) as a cell without numbers."""
    return tuple(c if isinstance(c, Cell) else Cell(c) for c in cells)


def write_report(exp, results: list[dict], out: Path, meta: dict) -> dict:
    """``table.md``, ``table.csv`` and ``per_frame.png`` from the run results; returns the summary: ``table``
    (table.md's text), ``tables`` (the same without the closing line about this invocation), ``report`` (those
    tables as data, :class:`~tracker.app.report_tables.Report`), ``runs`` and ``run_seconds`` (all runs' time,
    s)."""
    rows = list(dict.fromkeys(r["run"]["row"] for r in results))
    seqs = list(dict.fromkeys(r["run"]["sequence"] for r in results))
    by = {}
    for r in results:
        by.setdefault((r["run"]["row"], r["run"]["sequence"]), []).append(r)
    for group in by.values():
        group.sort(key=lambda r: r["run"]["seed_index"])

    free = [s for s in seqs if not all(has_truth(by.get((row, s), [])) for row in rows)]
    all_seqs, seqs = seqs, [s for s in seqs if s not in free]  # the marker error's tables: ground truth only
    csv_rows = [["metric", "row", "sequence", "mean", "std", "runs", "seconds_per_frame"]]
    tables = [_metric_table(metric, title, rows, seqs, by, csv_rows) for metric, _, title in METRICS if seqs]
    labels = [p.label for p in exp.priors]

    def split_row(row: str) -> tuple[str, str]:
        return split_row_label(row, labels)

    pairs = []  # (row, the row it is compared with)
    for row in rows:
        label, variant = split_row(row)
        if exp.paired == "all":
            pairs += [(row, other) for other in rows if other != row and split_row(other)[1] == variant
                      and rows.index(other) < rows.index(row)]
        elif label != exp.baseline and exp.baseline + variant in rows:
            pairs.append((row, exp.baseline + variant))
    if pairs and seqs:
        tables.append(_paired_table(exp, pairs, seqs, by))
    if free:
        tables += _tables_without_truth(csv_rows, rows, free, by, out / "runs")
    groups = _replicate_groups(exp, rows, split_row)
    tables += _replicate_tables(csv_rows, groups if seqs else {}, seqs, lambda row, s: [
        per_run(r, PRIMARY) for r in by.get((row, s), [])])
    intro: Text = (Code(exp.path.name), (f": {exp.seeds} seed(s) per configuration, master seed {exp.seed}; "
                                         "mean ± std over seeds of each run's mean over its tracked frames."))
    report = Report(exp.description or exp.path.stem, (intro,), tuple(tables))
    text = markdown(report)  # without the line about this invocation (report.html is the same on a rerun)
    cpu = sum({r["run"]["key"]: r.get("wall_seconds", 0.0) for r in results}.values())
    table = (text + f"\n{meta['runs']} runs, {cpu:.0f} s of run time in all; this invocation ran {meta['ran_now']} "
             f"of them with {meta['jobs']} {meta['backend']} job(s) in {meta['wall_seconds_now']:.0f} s; package "
             f"version {meta['version']}.\n")
    write_text_atomic(out / "table.md", table)
    buf = io.StringIO()
    csv.writer(buf).writerows(csv_rows)
    write_text_atomic(out / "table.csv", buf.getvalue())
    _plot(out / "per_frame.png", _plotted_rows(rows, groups), all_seqs, by)
    return {"table": table, "tables": text, "report": report, "runs": len(results), "run_seconds": cpu}


def _metric_table(metric: str, title: str, rows: list[str], seqs: list[str], by: dict, csv_rows: list) -> Table:
    """The table of one metric of :data:`METRICS` (``title`` its heading) over the sequences ``seqs`` (which have
    ground truth), with every row's seconds per frame; its lines of ``table.csv`` are added to ``csv_rows``."""
    body = []
    for row in rows:
        cells, secs = [], []
        for s in seqs:
            group = by.get((row, s), [])
            vals = [per_run(r, metric) for r in group]
            cells.append(_cell(vals))
            secs += [r["seconds_per_frame"] for r in group]
            if group and np.all(np.isfinite(vals)):
                mean, sd = summarize_runs(vals)
                csv_rows.append([metric, row, s, f"{mean:.4f}", f"{sd:.4f}", len(vals),
                                 f"{np.mean([r['seconds_per_frame'] for r in group]):.4f}"])
        body.append(_row(row, *cells, f"{np.mean(secs):.3f}"))
    return Table(title, ("prior", *seqs, "s/frame"), tuple(body), higher_is_better=metric.startswith("pck"))


def _paired_table(exp, pairs: list[tuple[str, str]], seqs: list[str], by: dict) -> Table:
    """The paired differences of :data:`PRIMARY` of every (row, compared row) of ``pairs``: the mean over the
    seed indices both have of (row - compared row), with its :func:`bootstrap_interval` where there are two or
    more."""
    body = []
    for row, base_row in pairs:
        cells = []
        for s in seqs:
            a = {r["run"]["seed_index"]: per_run(r, PRIMARY) for r in by.get((row, s), [])}
            b = {r["run"]["seed_index"]: per_run(r, PRIMARY) for r in by.get((base_row, s), [])}
            common = sorted(set(a) & set(b))
            d = np.array([a[i] - b[i] for i in common])
            if d.size == 0 or not np.all(np.isfinite(d)):
                cells.append(Cell("n/a"))
                continue
            if d.size == 1:
                cells.append(Cell(f"{d.mean():+.1f}"))
                continue
            lo, hi = bootstrap_interval(d)
            cells.append(Cell(f"{d.mean():+.1f} [{lo:+.1f}, {hi:+.1f}]", interval=(lo, hi)))
        body.append(_row(row, base_row, *cells))
    title = exp.baseline if exp.paired == "baseline" else "each other (row minus compared row)"
    return Table(f"Paired difference to {title} ({PRIMARY}, mm; 95% bootstrap interval over seeds)",
                 ("prior", "compared with", *seqs), tuple(body))


def _tables_without_truth(csv_rows: list, rows: list[str], seqs: list[str], by: dict, runs_dir: Path
                          ) -> list[Table]:
    """The tables of the sequences ``seqs`` that have no ground truth: the spread between seeds with the seconds
    per frame, and the distance to the reference reconstruction where the sequence has one (``by``: the results
    by ``(row, sequence)``). Their lines in ``table.csv`` are the metrics ``seed_spread`` (its std empty) and
    ``reference_distance``."""
    body = []
    for row in rows:
        cells, secs = [], []
        for s in seqs:
            group = by.get((row, s), [])
            secs += [r["seconds_per_frame"] for r in group]
            spread = seed_spread([_tracked_markers(r, runs_dir) for r in group])
            cells.append("n/a" if not np.isfinite(spread) else f"{spread:.1f}")
            if group and np.isfinite(spread):
                csv_rows.append(["seed_spread", row, s, f"{spread:.4f}", "", len(group),
                                 f"{np.mean([r['seconds_per_frame'] for r in group]):.4f}"])
        body.append(_row(row, *cells, f"{np.mean(secs):.3f}"))
    spread_note: Text = (("No ground truth, so no marker error: each cell is how far apart the seeds put the markers "
                          "(the mean distance of a run's markers from the mean over seeds, over its tracked frames; "
                          "n/a with one seed), which says how repeatable a prior is, not how right."),)
    tables = [Table("Without ground truth: spread between seeds (mm)", ("prior", *seqs, "s/frame"), tuple(body),
                    notes=(spread_note,))]
    referenced = [s for s in seqs if any(reference_values(r) for row in rows for r in by.get((row, s), []))]
    if not referenced:
        return tables
    body = []
    for row in rows:
        cells = []
        for s in referenced:
            group = by.get((row, s), [])
            vals = [r["reference"]["mean"] for r in group if reference_values(r)]
            cells.append(_cell(vals) if len(vals) == len(group) else Cell("n/a"))
            if group and len(vals) == len(group):
                mean, sd = summarize_runs(vals)
                csv_rows.append(["reference_distance", row, s, f"{mean:.4f}", f"{sd:.4f}", len(vals),
                                 f"{np.mean([r['seconds_per_frame'] for r in group]):.4f}"])
        body.append(_row(row, *cells))
    note: Text = (("Mean ± std over seeds of each run's mean distance to the sequence's reference (its keypoints "
                   "mapped to our markers, one rigid alignment of the whole run, every frame of the run, as "),
                  Code("compare-trc"),
                  (" prints it). A reference is another method's estimate, not the truth, and its keypoints are not "
                   "our markers (a detector's hip is not the hip joint's centre): the distances hold that difference, "
                   "and compare priors with each other better than they measure error."))
    tables.append(Table("Distance to the reference reconstruction (mm), after one rigid alignment",
                        ("prior", *referenced), tuple(body), notes=(note,)))
    return tables


def _replicate_groups(exp, rows: list[str], split_row) -> dict[tuple[str, str], list[str]]:
    """The rows of every ``train_seeds`` entry, grouped per variant (view set, likelihood, ...): (the entry's
    label, the variant) -> its rows, in row order."""
    group_of = {p.label: p.replicate_of for p in exp.priors if p.replicate_of is not None}
    members: dict[tuple[str, str], list[str]] = {}
    for row in rows:
        label, variant = split_row(row)
        if label in group_of:
            members.setdefault((group_of[label], variant), []).append(row)
    return members


def _group_name(group: str, variant: str, members: list[str]) -> str:
    """A ``train_seeds`` group's row name in ``table.csv`` and the plot: ``"LABEL (over N training seeds)"`` and
    the variant."""
    return f"{group} (over {len(members)} training seeds){variant}"


def _replicate_tables(csv_rows: list, groups: dict[tuple[str, str], list[str]], seqs: list[str],
                      errors: Callable[[str, str], list[float]]) -> list[Table]:
    """The "over training seeds" table of the ``groups`` (:func:`_replicate_groups`; none without groups): for
    each, the mean over its models of each model's absolute MPJPE (its mean over tracking seeds), the standard
    deviation between them, their range, and the mean standard deviation over tracking seeds within a model.
    ``errors(row, sequence)`` gives a row's per-run errors (mm). The means also go to ``table.csv`` as rows named
    like the group (their ``std`` is the spread between the models, ``runs`` all the models' runs), which
    :mod:`benchmarks.loso_summary` reads like any other."""
    if not groups:
        return []
    body = []
    for (group, variant), members in groups.items():
        cells = []
        name = _group_name(group, variant, members)
        for s in seqs:
            per_model = [errors(row, s) for row in members]
            if any(not v or not np.all(np.isfinite(v)) for v in per_model):
                cells.append(Cell("n/a"))
                continue
            means = [float(np.mean(v)) for v in per_model]
            mean, between = summarize_runs(means)
            within = float(np.mean([summarize_runs(v)[1] for v in per_model]))
            cells.append(Cell(f"{mean:.1f} ± {between:.1f} [{min(means):.1f}, {max(means):.1f}]; {within:.1f}",
                              mean=float(mean)))
            csv_rows.append([PRIMARY, name, s, f"{mean:.4f}", f"{between:.4f}",
                             sum(len(v) for v in per_model), ""])
        body.append(_row(f"{group}{variant}", str(len(members)), *cells))
    return [Table(f"Over training seeds ({PRIMARY}, mm): mean over models ± std between models [range]; mean std "
                  "over tracking seeds within a model", ("prior", "models", *seqs), tuple(body))]


# -- table.md -----------------------------------------------------------------------------------------------------

def markdown(report: Report) -> str:
    """``report`` as Markdown, ``table.md``'s text (without its closing line about the invocation): the title as
    a heading, the introduction, then every table under its own heading, its notes above it."""
    lines = [f"# {report.title}", ""] + [_markdown_text(t) for t in report.intro]
    for table in report.tables:
        lines += ["", f"## {table.title}", ""]
        for note in table.notes:
            lines += [_markdown_text(note), ""]
        lines.append(_markdown_row(table.header))
        lines.append("|---" * len(table.header) + "|")
        lines += [_markdown_row([c.text for c in row]) for row in table.rows]
    return "\n".join(lines) + "\n"


def _markdown_text(text: Text) -> str:
    """A line of text as Markdown: its :class:`~tracker.app.report_tables.Code` parts in backticks."""
    return "".join(f"`{part.text}`" if isinstance(part, Code) else part for part in text)


def _markdown_row(cells) -> str:
    """A Markdown table row of the texts ``cells``."""
    return "| " + " | ".join(cells) + " |"


def _plotted_rows(rows: list[str], groups: dict[tuple[str, str], list[str]]) -> dict[str, list[str]]:
    """The plot's lines: every row on its own, except the rows of a ``train_seeds`` group, which make one line
    from all their models' runs (at the place of the group's first row)."""
    group_of_row = {row: (_group_name(*key, members), members) for key, members in groups.items() for row in members}
    lines: dict[str, list[str]] = {}
    for row in rows:
        name, members = group_of_row.get(row, (row, [row]))
        lines.setdefault(name, members)
    return lines


def _rows_on(lines: dict[str, list[str]], sequence: str, by: dict) -> list[str]:
    """The rows of the plot's ``lines`` that have runs on ``sequence``."""
    return [member for members in lines.values() for member in members if (member, sequence) in by]


def _plot(path: Path, lines: dict[str, list[str]], seqs: list[str], by: dict) -> None:
    """:func:`per_frame_figure` written to ``path`` (PNG), cropped to what is drawn (labels and legend whole)."""
    fig = per_frame_figure(lines, seqs, by)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, bbox_inches="tight", pad_inches=0.1)


def per_frame_figure(lines: dict[str, list[str]], seqs: list[str], by: dict):
    """Per-frame absolute MPJPE of each line (a row, or a ``train_seeds`` group's rows together), mean over its
    runs with a ±1 std band, one panel per sequence (``by``: the results by ``(row, sequence)``); for a sequence
    without ground truth, the distance to its reference reconstruction instead, or a panel that says it has
    neither.

    Each prior gets its own colour (up to 20 distinct ones) and each view set its own line style, so rows
    stay apart however many there are; the legend sits to the right of the panels. The y label is short
    enough for the smallest panel."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    rows = list(lines)
    priors = list(dict.fromkeys(r.rpartition(", views ")[0] or r for r in rows))
    view_sets = list(dict.fromkeys(r.rpartition(", views ")[2] if ", views " in r else "" for r in rows))
    palette = colormaps["tab10" if len(priors) <= 10 else "tab20"]
    styles = ["-", "--", ":", "-."]
    height = max(3.2, 0.17 * len(rows) + 1.0)
    fig = Figure(figsize=(11.5, height * len(seqs)), dpi=110)
    axes = fig.subplots(len(seqs), 1, squeeze=False)[:, 0]
    for ax, s in zip(axes, seqs):
        truth = all(has_truth(by.get((row, s), [])) for row in _rows_on(lines, s, by))

        def values(r: dict) -> list[float] | None:
            return per_frame_values(r, PRIMARY) if truth else reference_values(r)

        def frames_of(r: dict) -> list[int]:
            return r["tracked_frames"] if truth else r["reference"]["frames"]

        drawn = False
        for row in rows:
            group = [r for member in lines[row] for r in by.get((member, s), []) if values(r)]
            if not group:
                continue
            drawn = True
            n = min(len(values(r)) for r in group)
            errs = np.array([values(r)[:n] for r in group])
            frames = np.array(frames_of(group[0])[:n])
            mean, sd = errs.mean(axis=0), errs.std(axis=0)
            prior, _, views = row.rpartition(", views ") if ", views " in row else (row, "", "")
            colour = palette(priors.index(prior) % palette.N)
            ax.plot(frames, mean, color=colour, linestyle=styles[view_sets.index(views) % len(styles)],
                    label=f"{row} ({errs.mean():.0f} mm)")
            ax.fill_between(frames, mean - sd, mean + sd, color=colour, alpha=0.12, linewidth=0)
        ax.set_title(s if truth else f"{s} (no ground truth)")
        ax.set_xlabel("frame")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        # "MPJPE, absolute (mm)"
        ax.set_ylabel(f"{CORE_METRICS[0].title.split(' (')[0]} (mm)" if truth else "to the reference (mm)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        if drawn:
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
        else:
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_ylabel("")
            ax.text(0.5, 0.5, "no ground truth and no reference to measure the runs against",
                    transform=ax.transAxes, ha="center", va="center", color="#5d6873")
    fig.tight_layout()
    return fig
