"""``compare``: run an experiment's grid in parallel (joblib, Dask or Ray), resumably, and write its tables.

Layout of the output folder::

    OUT/sequences/<hash>/    rendered sequences (cached by what determines them)
    OUT/models/<hash>.pt     trained models (cached likewise)
    OUT/runs/<hash>/         one finished run: result.json (settings, metrics, per-frame errors),
                             estimates.npz, run.log -- written under a temporary name, then renamed
    OUT/table.md, table.csv, per_frame.png, experiment.json

A run folder exists only once its run has finished, so an interrupted experiment (Ctrl-C, a killed
worker) resumes by running the grid again: finished runs are skipped, unfinished ones start over.
"""
from __future__ import annotations

import json
import os
import shutil
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from data_tools.files import atomic_path, write_text_atomic
from tracker.app.experiment import (
    Experiment, RunSpec, config_hash, expand_runs, file_hash, load_experiment, run_seed,
)
from tracker.core.errors import InputError

BACKENDS = ("joblib", "dask", "ray")


# -- preparing sequences and models ---------------------------------------------------------------------------

def _folder_hash(root: Path) -> str:
    """Content identity of an existing sequence folder: its small files' bytes and its images' names and sizes."""
    parts = []
    for p in sorted(root.rglob("*")):
        if not p.is_file():
            continue
        rel = str(p.relative_to(root))
        small = p.suffix.lower() in (".json", ".npz", ".txt", ".cal")
        parts.append([rel, file_hash(p) if small else p.stat().st_size])
    return config_hash(parts)


def prepare_sequences(exp: Experiment, out: Path, version: str, say: Callable[[str], None]
                      ) -> tuple[dict[str, Path], dict[str, str]]:
    """Sequence folders by name (rendering, once, those given as mocap) and their content hashes."""
    from tracker.app.api import synthesize

    paths, hashes = {}, {}
    for s in exp.sequences:
        if s.path is not None:
            paths[s.name], hashes[s.name] = s.path, _folder_hash(s.path)
            continue
        ident = {"mocap": file_hash(s.mocap), "skeleton": file_hash(s.skeleton) if s.skeleton else None,
                 "synth": s.synth, "fps": exp.fps, "version": version,
                 **({"then": file_hash(Path(s.synth["then"]))} if "then" in s.synth else {})}
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
        files = list(p.models)
        for t in p.train:
            ident = {"prior": p.name, "mocap": [[file_hash(m.path), m.start, m.frames] for m in t.mocap],
                     "skeletons": None if t.skeletons is None else [file_hash(m) for m in t.skeletons],
                     "options": t.options, "seed": t.seed, "fps": exp.fps, "version": version}
            path = out / "models" / f"{config_hash(ident)}.pt"
            if not path.exists():
                say(f"training {p.name} for {p.label!r} on {len(t.mocap)} clip(s)")
                try:
                    clips = load_clips(t.mocap, exp.fps, t.skeletons)
                except InputError as exc:
                    raise InputError(f"prior {p.label!r}: {exc}", exp.path) from None
                model = train(p.name, clips, fps=exp.fps, seed=t.seed, **t.options)
                with atomic_path(path) as tmp:
                    model.save(tmp)
            files.append(path)
        models[p.label] = tuple(files)
    return models


def load_clips(clips, fps: float, skeletons=None) -> list:
    """Retargeted training clips of :class:`~tracker.app.experiment.ClipSpec` entries, each cut to its range
    (``skeletons``: one ASF for all AMC clips or one per clip; default the one beside each)."""
    from data_tools.load import load_training_clips

    loaded = load_training_clips([m.path for m in clips], skeletons, fps)
    cut = [slice(m.start, None if m.frames is None else m.start + m.frames) for m in clips]
    out = [replace(c, poses=c.poses[k], markers=c.markers[k], model_markers=c.model_markers[k])
           for c, k in zip(loaded, cut)]
    for c, m in zip(out, clips):
        if len(c.poses) < 3:
            raise InputError(f"training clip {m.path.name} has {len(c.poses)} frame(s) from start {m.start}")
    return out


def prepare_scales(exp: Experiment) -> dict[str, np.ndarray | None]:
    """Random-walk scales by prior label, from each prior's ``train_mocap`` clips (None: the defaults)."""
    from tracker.core.representation import step_rms

    return {p.label: None if p.train_mocap is None else step_rms([c.poses for c in load_clips(p.train_mocap,
                                                                                              exp.fps)])
            for p in exp.priors}


def check_grid(exp: Experiment, sequence_paths: dict[str, Path], models: dict[str, tuple[Path, ...]],
               scales: dict[str, np.ndarray | None]) -> None:
    """Views in range, enough frames, and every prior (with its models) fits every sequence: one line naming
    the experiment file and the entry otherwise."""
    from tracker.app.api import build_prior, load_sequence

    for name, path in sequence_paths.items():
        seq = load_sequence(path)
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


# -- one run (executed in a worker) ---------------------------------------------------------------------------

def execute_run(spec: RunSpec) -> dict:
    """Track one run and write its folder ``runs/<key>/`` atomically; returns its summary (``result.json``)."""
    from tracker.app.api import track
    from tracker.app.threads import set_threads
    from tracker.app.api import load_sequence
    from tracker.core.metrics import marker_error, pck, procrustes_aligned_error

    set_threads(spec.threads)
    final = Path(spec.out) / spec.key
    if (final / "result.json").exists():
        return json.loads((final / "result.json").read_text())
    tmp = Path(spec.out) / f".{spec.key}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        t0 = time.perf_counter()
        with open(tmp / "run.log", "w", encoding="utf-8") as log:
            log.write(f"run {spec.key}: {spec.row} on {spec.sequence}, seed index {spec.seed_index}\n")

            def on_frame(step, err):
                log.write(f"frame {step.frame}: ess {step.ess:.0f}"
                          + ("" if err is None else f", marker error {err:.1f} mm") + "\n")

            seed = run_seed(spec.seed_entropy, spec.seed_index)
            seq = load_sequence(spec.sequence_path)
            run = track(seq, spec.prior, models=spec.models, likelihood=spec.likelihood, **spec.prior_options,
                        **spec.likelihood_options,
                        particles=spec.particles, views=spec.views, frames=spec.frames, seed=seed,
                        annealing_layers=spec.annealing_layers, resampling=spec.resampling,
                        known_frames=spec.known_frames,
                        step_std=None if spec.step_std is None else np.array(spec.step_std), on_frame=on_frame)
            log.write(f"done in {time.perf_counter() - t0:.1f} s\n")
        result = run.save(tmp)
        gt = seq.groundtruth
        if gt is not None:
            n0, T = run.first_tracked, len(run.poses)
            est, truth = run.markers[n0:], gt.markers[n0:T]
            result["per_frame_relative_error_mm"] = [round(float(e), 3)
                                                     for e in marker_error(est, truth, root_aligned=True)]
            result["per_frame_pa_mpjpe_mm"] = [round(float(e), 3) for e in procrustes_aligned_error(est, truth)]
            result["per_frame_pck150"] = [round(float(e), 2) for e in pck(est, truth, 150.0)]
        result["run"] = spec.as_dict()
        result["wall_seconds"] = time.perf_counter() - t0
        write_text_atomic(tmp / "result.json", json.dumps(result, indent=1))
        try:
            os.replace(tmp, final)
        except OSError:  # another worker finished the same run first
            shutil.rmtree(tmp, ignore_errors=True)
        return result
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


# -- executors --------------------------------------------------------------------------------------------------

def _ready() -> bool:
    """Imports a worker needs before its first run (the tracker, its plugins, torch)."""
    from tracker.app.api import available_priors

    available_priors()
    return True


def warm_joblib_workers(jobs: int):
    """Start joblib's worker processes and their imports in a background thread, so that they are ready when
    the runs start (they are reused by the next ``Parallel`` of the same size); returns the thread to join."""
    import threading

    from joblib import Parallel, delayed

    thread = threading.Thread(target=lambda: Parallel(n_jobs=jobs)(delayed(_ready)() for _ in range(jobs)),
                              daemon=True)
    thread.start()
    return thread


def run_all(specs: list[RunSpec], jobs: int, backend: str, address: str | None) -> Iterator[dict]:
    """Execute runs with the chosen backend, yielding each summary as it finishes (in any order)."""
    if backend == "joblib":
        from joblib import Parallel, delayed

        if jobs == 1:
            for s in specs:
                yield execute_run(s)
            return
        yield from Parallel(n_jobs=jobs, return_as="generator_unordered")(delayed(execute_run)(s) for s in specs)
    elif backend == "dask":
        try:
            from distributed import Client, LocalCluster, as_completed
        except ImportError:
            raise InputError("--backend dask needs the dask extra: pip install '.[dask]'") from None
        cluster = None if address else LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                                    dashboard_address=None)
        client = Client(address or cluster)
        try:
            for future in as_completed(client.map(execute_run, specs, pure=False)):
                yield future.result()
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    elif backend == "ray":
        try:
            import ray
        except ImportError:
            raise InputError("--backend ray needs the ray extra: pip install '.[ray]'") from None
        started = not ray.is_initialized()
        if started:
            ray.init(address=address, num_cpus=None if address else jobs, include_dashboard=False,
                     log_to_driver=False, configure_logging=False)
        try:
            remote = ray.remote(num_cpus=1)(execute_run)
            pending = [remote.remote(s) for s in specs]
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                yield ray.get(done[0])
        finally:
            if started:
                ray.shutdown()
    else:
        raise InputError(f"unknown backend {backend!r}; choose from {', '.join(BACKENDS)}")


# -- the whole experiment -------------------------------------------------------------------------------------

def compare(experiment: str | Path, out: str | Path, jobs: int = 1, backend: str = "joblib",
            address: str | None = None, threads: int | None = None, say: Callable[[str], None] = print,
            progress: bool = True) -> dict:
    """Run an experiment (validated whole first), skipping finished runs; write and return its tables."""
    import tracker
    from tracker.app.report import write_report
    from tracker.app.threads import share_of_cores

    if jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {jobs}")
    if backend not in BACKENDS:
        raise InputError(f"unknown backend {backend!r}; choose from {', '.join(BACKENDS)}")
    exp = load_experiment(experiment)
    from data_tools.files import check_output_folder

    out = check_output_folder(out)
    runs_dir = out / "runs"
    try:
        runs_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder ({exc.strerror})", out) from None
    for stale in runs_dir.glob(".*.tmp-*"):  # left by an interrupted run
        shutil.rmtree(stale, ignore_errors=True)
    warming = warm_joblib_workers(jobs) if backend == "joblib" and jobs > 1 else None
    version = tracker.__version__
    sequence_paths, sequence_hashes = prepare_sequences(exp, out, version, say)
    models = prepare_models(exp, out, version, say)
    scales = prepare_scales(exp)
    check_grid(exp, sequence_paths, models, scales)
    specs = expand_runs(exp, sequence_paths, sequence_hashes, models, scales, runs_dir, version)
    per_worker = threads or share_of_cores(jobs if backend == "joblib" or not address else 1)
    specs = [replace(s, threads=per_worker) for s in specs]
    unique = list({s.key: s for s in specs}.values())  # two rows that differ only in label run once
    todo = [s for s in unique if not (runs_dir / s.key / "result.json").exists()]
    say(f"{len(unique)} runs: {len(unique) - len(todo)} finished before (skipped), {len(todo)} to run "
        f"({backend}, {jobs} job(s), {per_worker} thread(s) each)")
    if warming is not None:  # the workers started while the experiment was prepared
        warming.join()
    summaries = {}
    t0 = time.perf_counter()
    bar = None
    if progress and todo:
        from tqdm import tqdm

        bar = tqdm(total=len(todo), desc="runs", unit="run")
    try:
        for res in run_all(todo, jobs, backend, address):
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
    meta = {"experiment": str(exp.path), "description": exp.description, "runs": len(unique),
            "ran_now": len(todo), "wall_seconds_now": wall,
            "run_seconds_now": sum(r.get("wall_seconds", 0.0) for r in summaries.values()),
            "jobs": jobs, "backend": backend, "threads_per_worker": per_worker, "version": version}
    write_text_atomic(out / "experiment.json", json.dumps(meta, indent=1))
    return write_report(exp, results, out, meta)


def _running_means(summaries: dict) -> str:
    by_row: dict[str, list[float]] = {}
    for r in summaries.values():
        if r.get("mean_error_mm") is not None:
            by_row.setdefault(r["run"]["row"], []).append(r["mean_error_mm"])
    return ", ".join(f"{row}: {np.mean(v):.0f} mm" for row, v in by_row.items())
