"""Render and observation time per 4-view 640x480 frame (run by hand: python benchmarks/render_observe_benchmark.py).

Render: the person mesh rasterised into 4 views against the scene depth (render_person), then
compositing with noise (compose), then PNG writing. Observation: silhouette by background
subtraction + edge map for 4 views, on synthetic frames and on the real bodytrack frame
(which has provided masks, so only edge maps are computed there).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from timing import mean_ms  # noqa: E402

from data_tools.motion.asf_amc import asf_amc_clip  # noqa: E402
from data_tools.motion.retarget import retarget  # noqa: E402
from data_tools.sequences.sequence import read_sequence, write_image  # noqa: E402
from data_tools.synthesis.render import compose, make_room, person_mesh, render_background, render_person  # noqa: E402
from likelihoods.observations import observe  # noqa: E402
from tracker.core.cameras import default_rig  # noqa: E402

SHARED = REPO.parent / "shared"


def main() -> None:
    mocap = SHARED / "mocap" / "cmu" / "07"
    result = retarget(asf_amc_clip(mocap / "07.asf", mocap / "07_11.amc"), fps=60)
    rig = default_rig(4)
    rng = np.random.default_rng(0)
    room = make_room(rng, rig)
    person = person_mesh(result.model, rng)
    t0 = time.perf_counter()
    plates = [render_background(c, room) for c in rig.cameras]
    print(f"background plates (once per sequence), 4 views: {(time.perf_counter() - t0) * 1000:.0f} ms")
    depths = [d for _, d in plates]
    pose = result.poses[60].copy()
    pose[:2] -= result.poses[:, :2].mean(axis=0)
    views = render_person(person, result.model, pose, rig, depths)
    t_person = mean_ms(lambda: render_person(person, result.model, pose, rig, depths), 20)
    t_compose = mean_ms(lambda: [compose(p[0], v, 1.0, 2.0, rng) for p, v in zip(plates, views)], 10)
    images = [compose(p[0], v, 1.0, 2.0, rng) for p, v in zip(plates, views)]
    with tempfile.TemporaryDirectory() as tmp:
        t_write = mean_ms(lambda: [write_image(Path(tmp) / f"{i}.png", im) for i, im in enumerate(images)], 5)
    print(f"render person, 4 views: {t_person:.1f} ms; compose + noise: {t_compose:.1f} ms; "
          f"PNG write: {t_write:.1f} ms; total {t_person + t_compose + t_write:.0f} ms per frame")
    backgrounds = [compose(p[0], views[0].__class__(np.zeros_like(p[0]), np.zeros(p[0].shape[:2], bool)), 1.0,
                           2.0, rng) for p in plates]
    t_obs = mean_ms(lambda: observe(images, backgrounds), 10)
    print(f"observations (silhouette + edges), synthetic, 4 views: {t_obs:.1f} ms per frame")
    bt = SHARED / "bodytrack" / "sequenceB_1"
    if bt.exists():
        seq = read_sequence(bt)
        imgs = [seq.image(0, v) for v in range(4)]
        masks = [seq.mask(0, v) for v in range(4)]
        t_bt = mean_ms(lambda: observe(imgs, masks=masks), 10)
        print(f"observations (edges; masks given), bodytrack, 4 views: {t_bt:.1f} ms per frame")


if __name__ == "__main__":
    main()
