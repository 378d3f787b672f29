"""``compare``: run an experiment's grid in parallel (joblib, Dask or Ray), resumably, and write its tables.

Layout of the output folder::

    OUT/sequences/<hash>/    rendered sequences (cached by what determines them)
    OUT/models/<hash>.pt     trained models (cached likewise)
    OUT/runs/<hash>/         one finished run: result.json (settings, metrics, per-frame errors),
                             estimates.npz, run.log -- written under a temporary name, then renamed
    OUT/videos/<hash>.mp4    report.html's videos (cached likewise)
    OUT/table.md, table.csv, per_frame.png, report.html (tracker.app.report_html), experiment.json

A run folder exists only once its run has finished, so an interrupted experiment (Ctrl-C, a killed
worker) resumes by running the grid again: finished runs are skipped, unfinished ones start over.
"""
from __future__ import annotations

import json
import logging
import os
import shutil
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np

from data_tools.io.files import atomic_path, first_missing, undone_unless_started, write_text_atomic, writing
from data_tools.io.fingerprints import CACHE_NAME, config_hash, file_hash, sequence_hash
from tracker.app.backends import EXECUTION_OPTIONS, execution_default, run_all, warm_joblib_workers
from tracker.app.clips import load_clip_specs
from tracker.app.experiment import load_experiment
from tracker.app.experiment_spec import Experiment
from tracker.app.run_grid import RunSpec, expand_runs, run_seed
from tracker.core.errors import InputError

log = logging.getLogger(__name__)


# -- preparing sequences and models ---------------------------------------------------------------------------

def prepare_sequences(exp: Experiment, out: Path, version: str, say: Callable[[str], None]
                      ) -> tuple[dict[str, Path], dict[str, str]]:
    """Sequence folders by name (rendering, once, those given as mocap) and their content hashes."""
    from tracker.app.api import synthesize

    paths, hashes = {}, {}
    for s in exp.sequences:
        if s.path is not None:
            # every file's bytes, hashed once and cached in OUT by size and modification time
            paths[s.name], hashes[s.name] = s.path, sequence_hash(s.path, out / CACHE_NAME)
            continue
        # content, never paths: a moved data root leaves the cache names (and so the run hashes) as they were
        second = {key: file_hash(Path(s.synth[key])) for key in ("then", "then_skeleton") if key in s.synth}
        ident = {"mocap": file_hash(s.mocap), "skeleton": file_hash(s.skeleton) if s.skeleton else None,
                 "synth": {k: v for k, v in s.synth.items() if k not in second}, "fps": exp.fps,
                 "version": version, **second}
        h = config_hash(ident)
        folder = out / "sequences" / h
        if not (folder / "meta.json").exists():  # synthesize renders under a temporary name, then renames
            say(f"rendering sequence {s.name!r} from {s.mocap.name}")
            synthesize(s.mocap, folder, skeleton=s.skeleton, fps=exp.fps, overwrite=True, **s.synth)
        paths[s.name], hashes[s.name] = folder, h
    return paths, hashes


def prepare_models(exp: Experiment, out: Path, version: str, say: Callable[[str], None]
                   ) -> dict[str, tuple[Path, ...]]:
    """Model files by prior label: the given ones, and those the experiment trains (once, cached by hash)."""
    from tracker.app.api import train

    models = {}
    for p in exp.priors:
        files = []
        for t in p.model_sources():  # given files, and trainings (a mixture's components: each its own prior)
            if isinstance(t, Path):
                files.append(t)
                continue
            name = t.prior or p.name
            ident = {"prior": name, "mocap": [[file_hash(m.path), m.start, m.frames]
                                                + ([] if m.joint_map is None else [m.joint_map]) for m in t.mocap],
                     "skeletons": None if t.skeletons is None else [file_hash(m) for m in t.skeletons],
                     "options": t.options, "seed": t.seed, "fps": exp.fps, "version": version}
            path = out / "models" / f"{config_hash(ident)}.pt"
            if not path.exists():
                say(f"training {name} for {p.label!r} on {len(t.mocap)} clip(s)")
                try:
                    clips = load_clip_specs(t.mocap, exp.fps, t.skeletons)
                except InputError as exc:
                    raise InputError(f"prior {p.label!r}: {exc}", exp.path) from None
                model = train(name, clips, fps=exp.fps, seed=t.seed, **t.options)
                with atomic_path(path) as tmp:
                    model.save(tmp)
            files.append(path)
        models[p.label] = tuple(files)
    return models


def prepare_scales(exp: Experiment) -> dict[str, np.ndarray | None]:
    """Random-walk scales by prior label, from each prior's ``train_mocap`` clips (None: the defaults)."""
    from tracker.core.representation import step_rms

    return {p.label: None if p.train_mocap is None else step_rms([c.poses for c in load_clip_specs(p.train_mocap,
                                                                                                   exp.fps)])
            for p in exp.priors}


def check_grid(exp: Experiment, sequence_paths: dict[str, Path], models: dict[str, tuple[Path, ...]],
               scales: dict[str, np.ndarray | None]) -> None:
    """Views in range, enough frames, a start (ground truth or ``init``) and a usable ``reference`` for every
    sequence, and every prior (with its models) fits every sequence: one line naming the experiment file and the
    entry otherwise."""
    from data_tools.sequences.reference import check_reference
    from tracker.app.api import build_prior, load_sequence
    from tracker.app.tracking import check_frames

    specs = {s.name: s for s in exp.sequences}
    for name, path in sequence_paths.items():
        seq = load_sequence(path)
        spec = specs[name]
        try:
            init = None if spec.init is None else read_init(spec.init, seq)
            if init is None and seq.groundtruth is None and seq.initial_poses is None:
                raise InputError("has no ground truth to start from: give init = \"POSES.npz\" (its first poses, "
                                 "as `pose-tracker initialise` writes them)")
            check_frames(seq, exp.tracking["frames"], exp.tracking["known_frames"], init)
            if spec.reference is not None:
                check_reference(spec.reference, reference_offset_of(spec, seq), exp.tracking["frames"] or
                                seq.n_frames)
        except InputError as exc:
            text = exc.reason if exc.path is None or Path(exc.path) == Path(path) else str(exc)  # file and line
            raise InputError(f"sequence {name!r}: {text}", exp.path) from None
        for vs in exp.tracking["views"]:
            if vs is not None and max(vs) >= seq.n_views:
                raise InputError(f"[tracking] views {vs} out of range for sequence {name!r} "
                                 f"({seq.n_views} cameras: 0..{seq.n_views - 1})", exp.path)
        frames = exp.tracking["frames"]
        if frames is not None and frames > seq.n_frames:
            raise InputError(f"[tracking] frames {frames} is past the end of sequence {name!r} "
                             f"({seq.n_frames} frames)", exp.path)
        for p in exp.priors:
            try:
                build_prior(p.name, seq, models[p.label], step_std=scales[p.label], **p.options)
            except InputError as exc:
                raise InputError(f"prior {p.label!r} on sequence {name!r}: {exc}", exp.path) from None


def read_init(path: str | Path, seq) -> np.ndarray:
    """A sequence's first poses ``n x D`` (rad, mm) from a poses .npz (``init``, as ``initialise`` writes it),
    checked against the sequence's body model."""
    from data_tools.sequences.estimates import read_poses_file

    return read_poses_file(path, "first poses (init)", seq.model)


def reference_offset_of(spec, seq) -> int:
    """The reference frame of a run's frame 0 for the sequence ``spec`` (its ``reference_offset``, else the
    default of ``compare-trc``: :func:`data_tools.sequences.reference.reference_offset`)."""
    from data_tools.sequences.reference import reference_offset

    return reference_offset(seq.meta) if spec.reference_offset is None else spec.reference_offset


def score_references(exp: Experiment, results: list[dict], runs_dir: Path) -> None:
    """Add to each run's result (``results``, in place) of a sequence with a ``reference`` its distances to that
    reconstruction (``"reference"``: :meth:`~data_tools.sequences.reference.ReferenceComparison.to_dict`), as
    ``compare-trc`` measures them: the run's markers, one rigid alignment, per joint, per frame and mean (mm)."""
    from data_tools.io.checks import load_npz
    from data_tools.sequences.reference import compare_to_trc
    from tracker.app.api import load_sequence

    specs = {s.name: s for s in exp.sequences if s.reference is not None}
    offsets: dict[str, int] = {}
    for r in results:
        spec = specs.get(r["run"]["sequence"])
        if spec is None:
            continue
        if spec.name not in offsets:
            offsets[spec.name] = reference_offset_of(spec, load_sequence(r["run"]["sequence_path"]))
        markers = load_npz(runs_dir / r["run"]["key"] / "estimates.npz", "estimates", ("markers",))["markers"]
        r["reference"] = compare_to_trc(markers, spec.reference, offsets[spec.name]).to_dict()


# -- one run (executed in a worker) ---------------------------------------------------------------------------

def execute_run(spec: RunSpec) -> dict:
    """Track one run and write its folder ``runs/<key>/`` atomically; returns its summary (``result.json``). A
    failed write (no space left, read-only, no permission) is one line naming the run's folder, and leaves the
    finished runs as they were."""
    from tracker.app.threads import set_threads

    set_threads(spec.threads)
    final = Path(spec.out) / spec.key
    if (final / "result.json").exists():
        return json.loads((final / "result.json").read_text())
    tmp = Path(spec.out) / f".{spec.key}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        with writing(final):
            return _execute_run(spec, final, tmp)
    except InputError as exc:  # a file of the temporary folder: named by the run's own folder instead
        shutil.rmtree(tmp, ignore_errors=True)
        if exc.path is not None and Path(exc.path).parent == tmp:
            raise InputError(exc.reason, final / Path(exc.path).name) from None
        raise
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        from tracker.app.tracking import TrackingInterrupted

        if isinstance(exc, TrackingInterrupted):  # Ctrl-C in the run's filter: the experiment is interrupted
            raise KeyboardInterrupt from None
        raise


def _execute_run(spec: RunSpec, final: Path, tmp: Path) -> dict:
    """:func:`execute_run` in the temporary folder ``tmp``, renamed to ``final`` when complete."""
    from tracker.app.api import load_sequence, track

    tmp.mkdir(parents=True)
    t0 = time.perf_counter()
    with open(tmp / "run.log", "w", encoding="utf-8") as log:
        log.write(f"run {spec.key}: {spec.row} on {spec.sequence}, seed index {spec.seed_index}\n")

        def on_frame(step, err):
            log.write(f"frame {step.frame}: ess {step.ess:.0f}"
                      + ("" if err is None else f", mpjpe_abs {err:.1f} mm") + "\n")

        seed = run_seed(spec.seed_entropy, spec.seed_index)
        seq = load_sequence(spec.sequence_path)
        init = None if spec.init is None else read_init(spec.init, seq)
        run = track(seq, spec.prior, models=spec.models, likelihood=spec.likelihood, init=init,
                    **spec.prior_options, **spec.likelihood_options, **spec.settings(), seed=seed,
                    step_std=None if spec.step_std is None else np.array(spec.step_std), on_frame=on_frame)
        log.write(f"done in {time.perf_counter() - t0:.1f} s\n")
    result = run.save(tmp, overwrite=True)  # every metric, as track writes it
    result["run"] = spec.as_dict()
    result["wall_seconds"] = time.perf_counter() - t0
    write_text_atomic(tmp / "result.json", json.dumps(result, indent=1))
    try:
        os.replace(tmp, final)
    except OSError:  # another worker finished the same run first
        if not (final / "result.json").exists():
            raise
        shutil.rmtree(tmp, ignore_errors=True)
    return result


# -- the whole experiment -------------------------------------------------------------------------------------

def compare(experiment: str | Path, out: str | Path, jobs: int = execution_default("jobs"),
            backend: str = execution_default("backend"), address: str | None = execution_default("address"),
            threads: int | None = None, say: Callable[[str], None] | None = None, progress: bool = True,
            data_root: str | Path | None = None, videos: bool = True, overwrite: bool = False,
            command: str | None = None) -> dict:
    """Run an experiment (validated whole first), skipping finished runs; write and return its tables.

    ``out`` is a new or empty folder, or an earlier compare output (it holds ``experiment.json``), which is
    continued; another non-empty folder is refused unless ``overwrite``, and a sequence folder of the
    experiment is never written into.

    ``data_root`` replaces the experiment file's ``data_root`` (see :mod:`tracker.app.experiment`); ``videos=False``
    leaves the overlay videos out of ``report.html``. ``say`` receives the lines on what is being done (default:
    this module's logger, at INFO); ``progress`` shows the runs' progress (a bar on a terminal, a line now and then
    in a log: :func:`tracker.app.console.progress_bar`). ``command`` is the command line recorded in
    ``report.html`` (default: the equivalent ``pose-tracker compare`` line).

    A refusal (a bad experiment, a prior that does not fit a sequence) leaves nothing behind that was not there
    before; an interruption (Ctrl-C) keeps every finished run, and the same call continues. ``experiment.json``
    says ``"complete": true`` once every run has finished and the tables are written."""
    say = say or log.info
    import tracker
    from tracker.app.report import write_report
    from tracker.app.threads import share_of_cores

    given = {"jobs": jobs, "backend": backend, "address": address}
    jobs, backend, address = (o.parse(given[o.name], "compare") for o in EXECUTION_OPTIONS)
    exp = load_experiment(experiment, data_root=data_root)
    from data_tools.io.files import check_not_inside, check_output_folder

    ours = (Path(out) / "experiment.json").is_file()  # an earlier compare output: continued, finished runs kept
    out = check_output_folder(out, empty=not (overwrite or ours))
    check_not_inside(out, {f"sequence folder of {s.name!r}": s.path for s in exp.sequences if s.path is not None})
    runs_dir = out / "runs"
    version = tracker.__version__
    warming = None
    # a refusal while the experiment is prepared (a prior that does not fit a sequence) leaves nothing behind
    with undone_unless_started(*(() if ours else (first_missing(out),)), on=(InputError,)):
        with writing(runs_dir):
            runs_dir.mkdir(parents=True, exist_ok=True)
        if not ours:  # marks the folder as a compare output from the start, so an interrupted one is continued
            _write_progress(out, exp, version, None)
        for stale in runs_dir.glob(".*.tmp-*"):  # left by an interrupted run
            shutil.rmtree(stale, ignore_errors=True)
        warming = warm_joblib_workers(jobs) if backend == "joblib" and jobs > 1 else None
        sequence_paths, sequence_hashes = prepare_sequences(exp, out, version, say)
        models = prepare_models(exp, out, version, say)
        scales = prepare_scales(exp)
        check_grid(exp, sequence_paths, models, scales)
    specs = expand_runs(exp, sequence_paths, sequence_hashes, models, scales, runs_dir, version)
    per_worker = threads or share_of_cores(jobs if backend == "joblib" or not address else 1)
    specs = [replace(s, threads=per_worker) for s in specs]
    unique = list({s.key: s for s in specs}.values())  # two rows that differ only in label run once
    _write_progress(out, exp, version, len(unique))
    todo = [s for s in unique if not (runs_dir / s.key / "result.json").exists()]
    say(f"{len(unique)} runs: {len(unique) - len(todo)} finished before (skipped), {len(todo)} to run "
        f"({backend}, {jobs} job(s), {per_worker} thread(s) each)")
    if warming is not None:  # the workers started while the experiment was prepared
        warming.join()
    summaries = {}
    t0 = time.perf_counter()
    bar = None
    if progress and todo:
        from tracker.app.console import progress_bar

        bar = progress_bar(total=len(todo), desc="runs", unit="run", shown=True)
    try:
        for res in run_all(todo, jobs, backend, address, execute_run):
            summaries[res["run"]["key"]] = res
            if bar is not None:
                bar.update(1)
                bar.set_postfix_str(_running_means(summaries))
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    results = []
    for s in specs:  # each run under the labels of this experiment file, whatever it was labelled when it ran
        r = json.loads((runs_dir / s.key / "result.json").read_text())
        r["run"] = s.as_dict()
        results.append(r)
    score_references(exp, results, runs_dir)
    meta = {"experiment": str(exp.path), "description": exp.description, "runs": len(unique),
            "ran_now": len(todo), "wall_seconds_now": wall,
            "run_seconds_now": sum(r.get("wall_seconds", 0.0) for r in summaries.values()),
            "jobs": jobs, "backend": backend, "threads_per_worker": per_worker, "version": version,
            "data_root": None if exp.data_root is None else str(exp.data_root), "complete": True}
    summary = write_report(exp, results, out, meta)
    from tracker.app.report_html import compare_command, write_html_report

    command = command or compare_command(experiment, out, jobs, backend, address, data_root, videos)
    summary.update(write_html_report(exp, results, out, summary["report"], meta, command, videos, say))
    write_text_atomic(out / "experiment.json", json.dumps(meta, indent=1))  # last: complete once all is written
    return summary


def _write_progress(out: Path, exp: Experiment, version: str, runs: int | None) -> None:
    """``experiment.json`` of an experiment under way: not complete, with its number of runs once known."""
    write_text_atomic(out / "experiment.json", json.dumps({"experiment": str(exp.path), "version": version,
                                                           "runs": runs, "complete": False}, indent=1))


def finished_runs(out: str | Path) -> tuple[int, int | None]:
    """How many runs of the compare output ``out`` have finished, and how many it has (None before that is
    known)."""
    out = Path(out)
    try:
        total = json.loads((out / "experiment.json").read_text(encoding="utf-8")).get("runs")
    except (OSError, ValueError, AttributeError):
        total = None
    return sum(1 for _ in (out / "runs").glob("*/result.json")), total


def _running_means(summaries: dict) -> str:
    from tracker.app.report import PRIMARY, per_frame_values

    by_row: dict[str, list[float]] = {}
    for r in summaries.values():
        values = per_frame_values(r, PRIMARY)
        if values:
            by_row.setdefault(r["run"]["row"], []).append(float(np.mean(values)))
    return ", ".join(f"{row}: {np.mean(v):.0f} mm" for row, v in by_row.items())
