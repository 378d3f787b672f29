"""How the cost of tracking grows (run by hand: python benchmarks/scaling.py [--frames 60] [--lengths ...]).

CMU 07_11 (from ../shared) rendered once into 8 cameras (``--frames`` frames); the zero-velocity prior, one
annealing layer, one thread. Each configuration runs in a process of its own, so its peak resident memory is its
own:

* particles 250 to 16,000 with 4 views,
* views 1 to 8 with 1000 particles,
* sequence lengths of 100 to 2,000 frames (``--lengths``) with 1000 particles and 4 views: the rendered frames
  played forwards and backwards in turn (their files linked, the ground truth likewise), so that the motion
  stays continuous at any length without rendering thousands of frames,

and prints the median time per tracked frame (each frame's wall time past the first, so the first frame's
compiling is left out) and the peak resident memory. The fitted exponents are the slopes of log(time) against
log(particles) and log(views): 1 is linear. Memory against the sequence length shows whether anything grows with
the frames beyond the recorded estimates.
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
PARTICLES = (250, 500, 1000, 2000, 4000, 8000, 16000)
VIEWS = (1, 2, 4, 8)


def one(sequence: str, particles: int, views: int, frames: int) -> dict:
    """Track ``frames`` frames in this process and return its timings and peak memory."""
    import tracker

    tracker.set_threads(1)
    run = tracker.track(sequence, "zero-velocity", particles=particles, views=list(range(views)), frames=frames,
                        seed=0, annealing_layers=1)
    return {"particles": particles, "views": views, "frames": frames,
            "seconds_per_frame": float(np.median(run.records["wall_seconds"][1:])),
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def run(sequence: Path, particles: int, views: int, frames: int) -> dict:
    done = subprocess.run([sys.executable, __file__, "--one", str(sequence), str(particles), str(views), str(frames)],
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def looped(sequence: Path, out: Path, frames: int) -> Path:
    """A sequence of ``frames`` frames at ``out``: those of ``sequence`` forwards, backwards, forwards, ...
    (image files hard-linked, or copied where links cannot be made; ground truth in the same order)."""
    import shutil

    n = len(list((sequence / "images" / "cam0").glob("*.png")))
    cycle = list(range(n)) + list(range(n - 2, 0, -1))
    order = [cycle[k % len(cycle)] for k in range(frames)]
    if (out / "meta.json").exists() and json.loads((out / "meta.json").read_text())["frames"] == frames:
        return out
    shutil.rmtree(out, ignore_errors=True)
    for camera in sorted((sequence / "images").iterdir()):
        (out / "images" / camera.name).mkdir(parents=True)
        for k, src in enumerate(order):
            source, target = camera / f"{src:06d}.png", out / "images" / camera.name / f"{k:06d}.png"
            try:
                target.hardlink_to(source)
            except OSError:
                shutil.copyfile(source, target)
    shutil.copytree(sequence / "background", out / "background")
    shutil.copyfile(sequence / "cameras.json", out / "cameras.json")
    truth = np.load(sequence / "groundtruth.npz")
    np.savez(out / "groundtruth.npz", poses=truth["poses"][order], markers=truth["markers"][order], fps=truth["fps"])
    meta = json.loads((sequence / "meta.json").read_text())
    (out / "meta.json").write_text(json.dumps({**meta, "frames": frames}))
    return out


def slope(x, y) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60, help="frames rendered; the longest run tracks them all")
    parser.add_argument("--lengths", type=int, nargs="+", default=[100, 500, 1000, 2000],
                        help="sequence lengths (frames) measured with 1000 particles and 4 views")
    parser.add_argument("--out", type=Path, default=None, help="keep the rendered sequence here")
    parser.add_argument("--one", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        seq, p, v, f = args.one
        print(json.dumps(one(seq, int(p), int(v), int(f))))
        return
    import tracker

    root = args.out or Path(tempfile.mkdtemp(prefix="scaling_"))
    sequence = root / "walk_8_cameras"
    if not (sequence / "meta.json").exists():
        mocap = SHARED / "mocap" / "cmu" / "07" / "07_11.amc"
        tracker.synthesize(mocap, sequence, cameras=8, frames=args.frames, overwrite=True)
    short = min(22, args.frames)  # 20 tracked frames after the 2 known ones
    by_particles = [run(sequence, p, 4, short) for p in PARTICLES]
    by_views = [run(sequence, 1000, v, short) for v in VIEWS]
    lengths = sorted(args.lengths)
    by_length = [run(looped(sequence, root / f"walk_{f}_frames", f), 1000, 4, f) for f in lengths]
    for title, rows in (("particles, 4 views", by_particles), ("views, 1000 particles", by_views),
                        ("frames, 1000 particles, 4 views", by_length)):
        print(f"\n{title}")
        for r in rows:
            print(f"  {r['particles']:>6} particles {r['views']} views {r['frames']:>5} frames: "
                  f"{1000 * r['seconds_per_frame']:8.1f} ms/frame, peak {r['peak_rss_mb']:7.0f} MB")
    print(f"\nexponent in particles: {slope([r['particles'] for r in by_particles], [r['seconds_per_frame'] for r in by_particles]):.2f}"
          f" (1000 and up: {slope([r['particles'] for r in by_particles[2:]], [r['seconds_per_frame'] for r in by_particles[2:]]):.2f})")
    print(f"exponent in views: {slope([r['views'] for r in by_views], [r['seconds_per_frame'] for r in by_views]):.2f}")
    for name, rows, key in (("particle", by_particles, "particles"), ("view", by_views, "views")):
        b1, b0 = np.polyfit([r[key] for r in rows], [r["seconds_per_frame"] for r in rows], 1)
        print(f"time per frame = {1000 * b0:.1f} ms + {1e6 * b1:.2f} us per {name} (least squares)")
    print(f"peak memory from {lengths[0]} to {lengths[-1]} frames: "
          f"{by_length[0]['peak_rss_mb']:.0f} -> {by_length[-1]['peak_rss_mb']:.0f} MB; time per frame "
          f"{1000 * by_length[0]['seconds_per_frame']:.1f} -> {1000 * by_length[-1]['seconds_per_frame']:.1f} ms")


if __name__ == "__main__":
    main()
