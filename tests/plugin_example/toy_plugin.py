"""A toy plugin: a prior, a likelihood and a mocap reader, each registered as a third-party package registers
its own (entry-point group ``pose_tracker.plugins``, or ``pose-tracker --plugin toy_plugin.py``).

- ``toy-damped-walk``: a second-order walk whose velocity each particle keeps with a damping factor of its own
  (per-particle state);
- ``toy-marker-mask``: scores the body model's 15 markers against the frame's foreground masks;
- ``.toypts``: a text file of named points in centimetres, y up (converted to mm, z up on reading).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from data_tools.motion.load import apply_joint_map
from data_tools.motion.mocap import Y_UP_TO_Z_UP, MocapClip
from data_tools.motion.readers import ReadOptions, register_mocap_reader
from tracker.core.errors import InputError
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.prior import MotionPrior
from tracker.engine.registry import Option, register_likelihood, register_prior


class ToyDampedWalk(MotionPrior):
    """``x_t = x_{t-1} + a_p (x_{t-1} - x_{t-2}) + N(0, diag(std^2))`` with a damping ``a_p`` drawn per
    particle in [0.2, 0.8] when the particles start (``std``: ``(D,)``, mm and radians per frame)."""

    name = "toy-damped-walk"
    order = 2

    def __init__(self, std: np.ndarray):
        self.std = np.asarray(std, float)

    def start(self, known, n_particles, rng):
        return {"damping": rng.uniform(0.2, 0.8, n_particles)}

    def sample(self, history, available, state, rng):
        velocity = history[:, -1] - history[:, -2] if available >= 2 else 0.0
        poses = history[:, -1] + state["damping"][:, None] * velocity
        return poses + self.std * rng.standard_normal(poses.shape), dict(state)

    def diffusion_std(self):
        return self.std


@register_prior("toy-damped-walk", summary="a damped second-order walk (a toy plugin's prior)")
def build_toy_damped_walk(context, model_files, options):
    return ToyDampedWalk(context.step_std())


class ToyMarkerMask(Likelihood):
    """``-sharpness`` times the mean over views and markers of ``(1 - mask)^2`` at each marker's pixel (1 for a
    marker outside the image or behind the camera); ``-inf`` for a pose outside the body's limits. Frames need
    foreground masks."""

    name = "toy-marker-mask"

    def __init__(self, model, rig, sharpness: float):
        self.model, self.rig, self.sharpness = model, rig, sharpness

    def prepare(self, frame: Frame) -> FrameLikelihood:
        if frame.masks is None:
            raise InputError(f"{self.name} needs foreground masks; frame {frame.index} has none")
        if frame.n_views != len(self.rig):
            raise InputError(f"frame {frame.index} has {frame.n_views} views but the rig has {len(self.rig)} "
                             "cameras")
        masks = [np.asarray(m, float) for m in frame.masks]
        return _MaskScorer(self, masks)


class _MaskScorer(FrameLikelihood):
    def __init__(self, likelihood: ToyMarkerMask, masks: list[np.ndarray]):
        self.likelihood, self.masks = likelihood, masks

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        from tracker.core.kinematics import markers

        model, rig = self.likelihood.model, self.likelihood.rig
        poses = np.asarray(poses, float)
        if poses.ndim != 2 or poses.shape[1] != model.n_dofs:
            raise InputError(f"poses must be P x {model.n_dofs}, got {poses.shape}")
        valid = model.within_limits(poses)
        points = markers(model, np.where(valid[:, None], poses, model.rest_pose()))  # P x 15 x 3
        pixels, depth = rig.project(points)  # P x V x 15 x 2, P x V x 15
        cost = np.ones(depth.shape)
        for v, mask in enumerate(self.masks):
            x, y = np.rint(pixels[:, v, :, 0]), np.rint(pixels[:, v, :, 1])
            inside = (depth[:, v] > 0) & (x >= 0) & (y >= 0) & (x < mask.shape[1]) & (y < mask.shape[0])
            xi, yi = np.where(inside, x, 0).astype(int), np.where(inside, y, 0).astype(int)
            cost[:, v] = np.where(inside, (1.0 - mask[yi, xi]) ** 2, 1.0)
        return np.where(valid, -self.likelihood.sharpness * cost.mean(axis=(1, 2)), -np.inf)


@register_likelihood("toy-marker-mask", summary="markers against foreground masks (a toy plugin's likelihood)",
                     options=(Option("sharpness", float, 10.0, "likelihood sharpness", minimum=0.0, strict=True,
                                     maximum=1e6),))
def build_toy_marker_mask(context, options):
    return ToyMarkerMask(context.body_model, context.rig, options["sharpness"])


@register_mocap_reader(".toypts", "toy points", summary="named points in cm, y up, one frame a line")
def read_toy_points(path: Path, options: ReadOptions) -> MocapClip:
    """A ``.toypts`` file: a line ``fps RATE``, a line ``names A B ...`` (J names), then one line of ``3 J``
    numbers (cm, y up) a frame."""
    lines = path.read_text().splitlines()
    if len(lines) < 3 or not lines[0].startswith("fps ") or not lines[1].startswith("names "):
        raise InputError("not a toy points file (expected 'fps RATE', 'names ...' and frames)", path)
    try:
        fps = float(lines[0].split()[1])
    except ValueError:
        raise InputError(f"frame rate {lines[0].split()[1]!r} is not a number", path, 1) from None
    names = lines[1].split()[1:]
    rows = []
    for k, line in enumerate(lines[2:], start=3):
        try:
            row = np.array(line.split(), float)
        except ValueError:
            raise InputError("expected numbers", path, k) from None
        if row.shape != (3 * len(names),) or not np.all(np.isfinite(row)):
            raise InputError(f"expected {3 * len(names)} finite numbers, got {row.size}", path, k)
        rows.append(row)
    positions = np.stack(rows).reshape(len(rows), len(names), 3) * 10.0 @ Y_UP_TO_Z_UP.T  # cm to mm, y to z up
    clip = MocapClip(str(path), positions, names, fps, "asf", unit="cm", up="y")
    return apply_joint_map(clip, options.joint_map)


def write_toy_points(path: Path, names: list[str], positions_mm: np.ndarray, fps: float) -> Path:
    """Positions ``T x J x 3`` (mm, z up) of points ``names`` written as a ``.toypts`` file (cm, y up)."""
    rows = (positions_mm @ Y_UP_TO_Z_UP / 10.0).reshape(len(positions_mm), -1)
    path.write_text(f"fps {fps:g}\nnames {' '.join(names)}\n" +
                    "".join(" ".join(f"{v:.4f}" for v in row) + "\n" for row in rows))
    return path
