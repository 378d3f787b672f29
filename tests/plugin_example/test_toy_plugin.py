"""The toy plugin's own tests: each of its extension points inherits the toolkit's contract tests
(:mod:`tracker.testing`) and fills the factories. Nothing here needs shared data: the plugin's data are the
CMU walk shipped with the package and a frame drawn here."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from data_tools.motion.asf_amc import asf_amc_clip
from data_tools.samples import sample_walks
from tracker.core.body import fifteen_cone_model
from tracker.core.cameras import default_rig
from tracker.core.kinematics import markers
from tracker.engine.likelihood import Frame
from tracker.testing import LikelihoodContract, MocapReaderContract, PriorContract

from .toy_plugin import ToyMarkerMask, write_toy_points

MODEL = fifteen_cone_model()


def walking_poses(frames: int = 8) -> np.ndarray:
    """Poses ``T x 40`` of a body walking along x at 20 mm per frame, swinging its legs (radians)."""
    poses = np.repeat(MODEL.rest_pose()[None], frames, axis=0)
    poses[:, 0] += 20.0 * np.arange(frames)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        poses[:, MODEL.dof_index(f"{side}_hip_x")] = sign * 0.3 * np.sin(np.arange(frames) / 3.0)
    return poses


@pytest.fixture(scope="module", autouse=True)
def registered():
    """The plugin's entries, registered when :mod:`.toy_plugin` was imported, removed after this module."""
    from data_tools.motion.readers import READERS
    from tracker.engine.registry import LIKELIHOODS, PRIORS

    yield
    PRIORS.entries.pop("toy-damped-walk", None)
    LIKELIHOODS.entries.pop("toy-marker-mask", None)
    READERS.entries.pop(".toypts", None)


class TestToyDampedWalk(PriorContract):
    def make_prior(self):
        import tracker

        # through the registry, as a user builds it: the random-walk scale given as the API takes it
        class _Sequence:
            model, fps, root = MODEL, 60.0, Path("toy")

        return tracker.build_prior("toy-damped-walk", _Sequence(), step_std=np.r_[[5.0] * 3, [0.02] * 37])

    def known_poses(self):
        return walking_poses()


class TestToyMarkerMask(LikelihoodContract):
    rig = default_rig(2, 160, 120, focal=150.0)
    truth = walking_poses()[3]

    def make_likelihood(self):
        return ToyMarkerMask(MODEL, self.rig, sharpness=10.0)

    def make_frame(self):
        """Masks of discs 4 px across around the true pose's markers, in each view."""
        pixels, _ = self.rig.project(markers(MODEL, self.truth[None]))  # 1 x V x 15 x 2
        yy, xx = np.mgrid[:120, :160]
        masks = tuple(np.any(np.hypot(xx[..., None] - pixels[0, v, :, 0], yy[..., None] - pixels[0, v, :, 1]) < 4.0,
                             axis=-1).astype(float) for v in range(len(self.rig)))
        images = tuple((255 * m[..., None].repeat(3, axis=-1)).astype(np.uint8) for m in masks)
        return Frame(3, images, masks=masks)

    def make_poses(self, rng, n):
        poses = self.truth + rng.normal(0.0, 1.0, (n, MODEL.n_dofs)) * np.r_[[60.0] * 3, [0.1] * 37]
        return np.clip(poses, MODEL.lower, MODEL.upper)


class TestToyPoints(MocapReaderContract):
    suffix, reader_name, fps, frames = ".toypts", "toy points", 30.0, 40

    def make_file(self, folder):
        asf, amcs = sample_walks()
        clip = asf_amc_clip(asf, amcs[0])  # 120 Hz, mm, z up
        return write_toy_points(folder / "walk.toypts", clip.point_names, clip.positions[:160:4], 30.0)


@pytest.mark.slow
def test_the_command_line_converts_a_file_of_the_plugins_format(tmp_path):
    """``pose-tracker --plugin toy_plugin.py convert``: the plugin's reader, found by the suffix, feeds the
    retargeting (in a process of its own: this one registered the plugin under its package's name)."""
    import os
    import subprocess
    import sys

    from data_tools.motion.clip_io import load_converted_clip

    asf, amcs = sample_walks()
    clip = asf_amc_clip(asf, amcs[0])
    walk = write_toy_points(tmp_path / "walk.toypts", clip.point_names, clip.positions[:160:4], 30.0)
    plugin = Path(__file__).with_name("toy_plugin.py")
    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(repo), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-m", "tracker", "--plugin", str(plugin), "convert", "--mocap", str(walk),
                           "--fps", "30", "--out", str(tmp_path / "walk.npz")], capture_output=True, text=True,
                          env=env, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "walk.toypts: CMU ASF names, lengths in cm, y up, 30 Hz; 40 frames" in done.stdout
    assert len(load_converted_clip(tmp_path / "walk.npz").poses) == 40
