"""The GPU path: particle-view evaluations per second, whole-frame tracking speed, and the errors of
the device path against the CPU path on the same seeds. Run by hand on a machine with a GPU:

    python benchmarks/gpu_throughput.py [--device cuda] [--shared ../shared] [--frames 60]

1. Likelihood throughput on one synthetic frame (CMU 07_11 rendered into 4 views, 15-cone model) at 4000,
   16,000 and 64,000 particles: the whole call (numpy poses in, numpy log-likelihoods out: limits, the
   host-to-device copy and back) and the device work alone (poses already on the device), as particle-view
   evaluations per second; the CPU path (numpy, one thread) beside it.
2. Tracking 07_11 with the zero-velocity prior on the device and on the CPU, same seeds: mean error of each
   (the device path must give the CPU's errors within float tolerance) and seconds per frame, whole loop.
3. A CRBM (order 1, trained on 07_01 and 07_02 on the CPU) tracking on the device: seconds per frame and
   error at 1000 and 4000 particles (its Gibbs sampling runs on the device too).

The likelihood is the package's default, with the bidirectional term since 0.25.0; figures published for
earlier versions in docs/reference/performance.md are of the one-directional likelihood.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from data_tools.motion.asf_amc import asf_amc_clip  # noqa: E402
from data_tools.motion.retarget import retarget  # noqa: E402
from data_tools.sequences.sequence import read_sequence  # noqa: E402
from data_tools.synthesis.synth import SynthConfig, synthesize  # noqa: E402
from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood  # noqa: E402
from tracker import train, track  # noqa: E402
from tracker.core.arrays import torch_device  # noqa: E402
from tracker.core.representation import step_rms  # noqa: E402


def timed(fn, repeats: int, sync) -> float:
    """Median seconds of ``fn()`` over ``repeats`` calls after two warm-up calls (``sync()`` after each)."""
    for _ in range(2):
        fn()
        sync()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        sync()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def profile_call(scorer, truth: np.ndarray, rng: np.random.Generator, device: torch.device, P: int = 64000) -> None:
    """torch.profiler over one call of ``scorer`` on ``P`` poses near ``truth``: operators by device time."""
    from torch.profiler import ProfilerActivity, profile

    poses = truth + rng.standard_normal((P, truth.size)) * np.r_[[50.0] * 3, [0.05] * (truth.size - 3)]
    scorer(poses)
    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if device.type == "cuda" else [])
    with profile(activities=activities) as prof:
        scorer(poses)
        if device.type == "cuda":
            torch.cuda.synchronize()
    key = "cuda_time_total" if device.type == "cuda" else "cpu_time_total"
    print(f"\nprofile of one call, {P} particles x 4 views, operators by {key}:")
    print(prof.key_averages().table(sort_by=key, row_limit=18, max_name_column_width=40))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--shared", default=str(REPO.parent / "shared"))
    ap.add_argument("--frames", type=int, default=60, help="frames of the tracking runs (default 60)")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--compile", action="store_true", help="also time the device work under torch.compile")
    ap.add_argument("--profile", action="store_true",
                    help="profile one 64,000-particle call with torch.profiler (the kernels by device time)")
    ap.add_argument("--likelihood-only", action="store_true", help="skip the tracking runs (parts 2 and 3)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    device = torch_device(args.device)
    sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
    mocap = Path(args.shared) / "mocap" / "cmu" / "07"
    tmp = Path(tempfile.mkdtemp())
    walk = retarget(asf_amc_clip(mocap / "07.asf", mocap / "07_11.amc"), fps=60)
    seq = read_sequence(synthesize(walk, tmp / "walk", SynthConfig(frames=args.frames)).root)
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu"
    print(f"device: {name}; torch {torch.__version__}; host cores {os.cpu_count()}")

    print("\n1. likelihood throughput, one frame, 4 views, 15 cones (median of 10 calls)")
    rng = np.random.default_rng(0)
    k = min(30, args.frames - 1)
    truth = seq.groundtruth.poses[k]
    frame = seq.frame(k, range(4))
    cpu = EdgeSilhouetteLikelihood(seq.model, seq.rig).prepare(frame)
    dev_lik = EdgeSilhouetteLikelihood(seq.model, seq.rig, device=str(device))
    dev = dev_lik.prepare(frame)
    compiled = torch.compile(dev_lik.array_costs, dynamic=True) if args.compile else None
    print("| particles | device, whole call | device work alone | CPU path (1 thread) | max abs difference of "
          "log-likelihoods |" + (" device work, torch.compile |" if compiled else ""))
    print("|---|---|---|---|---|" + ("---|" if compiled else ""))
    for P in (4000, 16000, 64000):
        poses = truth + rng.standard_normal((P, truth.size)) * np.r_[[50.0] * 3, [0.05] * (truth.size - 3)]
        on_device = torch.as_tensor(poses, device=device)
        t_call = timed(lambda: dev(poses), 10, sync)
        with torch.no_grad():
            t_work = timed(lambda: dev_lik.array_costs(on_device, dev.maps), 10, sync)
        t_cpu = timed(lambda: cpu(poses), 3 if P > 4000 else 10, lambda: None)
        a, b = cpu(poses), dev(poses)
        ok = np.isfinite(a)
        diff = float(np.abs(a[ok] - b[ok]).max())
        pv = 4 * P
        extra = ""
        if compiled is not None:
            with torch.no_grad():
                t0 = time.perf_counter()
                compiled(on_device, dev.maps)
                sync()
                first = time.perf_counter() - t0
                t_comp = timed(lambda: compiled(on_device, dev.maps), 10, sync)
            extra = f" {t_comp * 1e3:.2f} ms = {pv / t_comp:.3g} /s (first call {first:.1f} s) |"
        print(f"| {P} | {t_call * 1e3:.2f} ms = {pv / t_call:.3g} particle-views/s | {t_work * 1e3:.2f} ms = "
              f"{pv / t_work:.3g} /s | {t_cpu * 1e3:.1f} ms = {pv / t_cpu:.3g} /s | {diff:.2g} |{extra}")

    if args.profile:
        profile_call(dev, truth, rng, device)
    if args.likelihood_only:
        return
    std = step_rms([retarget(asf_amc_clip(mocap / "07.asf", mocap / f"07_{i}.amc"), fps=60).poses
                    for i in ("01", "02")])
    print(f"\n2. tracking 07_11 ({args.frames} frames, 4 views), zero-velocity prior, seeds 0..{args.seeds - 1}")
    print("| particles | where | mean error (mm) per seed | s/frame (whole loop) | reading and observations "
          "(overlapped with the filter when threads > 1) | filter (prior, likelihood, resampling) |")
    print("|---|---|---|---|---|---|")
    for P in (1000, 4000, 16000):
        for where in ("cpu", str(device)):
            errs, spf, wait, filt = [], [], [], []
            for seed in range(args.seeds):
                run = track(seq, "zero-velocity", particles=P, seed=seed, step_std=std, device=where,
                            annealing_layers=1)  # plain SIR, as the figures in docs/reference/performance.md
                errs.append(run.mean_error)
                spf.append(run.seconds_per_frame)
                wait.append(np.median(run.records["load_seconds"] + run.records["observe_seconds"]))
                filt.append(np.median(run.records["filter_seconds"]))
            print(f"| {P} | {where} | {', '.join(f'{e:.3f}' for e in errs)} | {statistics.median(spf):.4f} | "
                  f"{statistics.median(wait):.4f} | {statistics.median(filt):.4f} |")
        if P >= 4000 and device.type == "cpu":
            break

    print(f"\n3. CRBM order 1 trained on 07_01, 07_02; tracking 07_11 on {device}")
    model_path = tmp / "crbm1.pt"
    t0 = time.perf_counter()
    model = train("crbm", [mocap / "07_01.amc", mocap / "07_02.amc"], order=1)
    model.save(model_path)
    print(f"trained in {time.perf_counter() - t0:.1f} s")
    print("| particles | mean error (mm) per seed | s/frame (whole loop) |")
    print("|---|---|---|")
    for P in (1000, 4000):
        errs, spf = [], []
        for seed in range(args.seeds):
            run = track(seq, "crbm", models=[model_path], particles=P, seed=seed, device=str(device),
                        annealing_layers=1)  # plain SIR, as the figures in docs/reference/performance.md
            errs.append(run.mean_error)
            spf.append(run.seconds_per_frame)
        print(f"| {P} | {', '.join(f'{e:.1f}' for e in errs)} | {statistics.median(spf):.4f} |")


if __name__ == "__main__":
    main()
