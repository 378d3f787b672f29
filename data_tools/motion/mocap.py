"""Motion capture clips as joint positions: the common result of every mocap reader.

Convention: world frame z up (mocap in y up is rotated on load by
:data:`Y_UP_TO_Z_UP`), millimetres, frames on the leading axis. A clip keeps
the positions of all its skeleton's points; :func:`marker_positions` picks the
15 HumanEva-style markers (and the extra points retargeting fits) by the
skeleton's naming convention.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from data_tools.io.checks import MAX_FPS, MIN_FPS, check_range
from data_tools.motion.skeleton_points import PointPlan, plan_points
from tracker.core.body import EXTRA_POINT_NAMES, MARKER_NAMES
from tracker.core.errors import InputError
from tracker.core.timewarp import MIN_SPEED, warped_length

#: Rotation taking y-up mocap coordinates to our z-up world: (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

MM_PER_INCH = 25.4


@dataclass
class MocapClip:
    """A mocap clip as positions of named skeleton points.

    ``positions`` ``T x J x 3`` (mm, z up), ``point_names`` J names (ASF: bone
    ends, named by bone, plus ``root``; BVH: joint origins by joint name plus
    ``<joint>_end`` for end sites), ``fps`` frames per second, ``style``
    ``'asf'`` or ``'bvh'`` (selects the naming conventions tried). ``plan`` says which points are the body's
    (None: the best naming convention, found when first asked); ``unit`` and ``up`` say how lengths and axes
    were read (for the summary); ``notes`` what else a user should know.
    """

    path: str
    positions: np.ndarray
    point_names: list[str]
    fps: float
    style: str
    notes: list[str] = field(default_factory=list)
    plan: PointPlan | None = None
    unit: str = ""
    up: str = "y"

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    def point_plan(self) -> PointPlan:
        """Where the body's points come from (planned from the names when no plan is set)."""
        if self.plan is None:
            self.plan = plan_points(self.point_names, self.style, source=self.path)
        return self.plan

    def summary(self) -> str:
        """How the file was read, in one phrase: its naming, length unit, up axis and frame rate."""
        parts = [self.point_plan().naming, f"lengths in {self.unit}" if self.unit else "", f"{self.up} up",
                 f"{self.fps:g} Hz"]
        return ", ".join(p for p in parts if p)



def check_fps(fps: float, what: str = "frame rate", source: str | None = None) -> float:
    """``fps`` as a float, refused unless a number in [:data:`~data_tools.io.checks.MIN_FPS`,
    :data:`~data_tools.io.checks.MAX_FPS`] Hz."""
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number, got {fps!r}", source) from None
    return float(check_range(fps, what, source, lo=MIN_FPS, hi=MAX_FPS, unit=" Hz"))


def frame_times(n_frames: int, source_fps: float, fps: float, source: str | None = None) -> np.ndarray:
    """The times (in frames of the source, fractional) of a clip of ``n_frames`` at ``source_fps`` sampled at
    ``fps``: ``k * source_fps / fps`` for ``k = 0, 1, ...`` up to the last frame, whole numbers kept exact (120
    to 60 Hz reads every second frame, as in Taylor 2009). Any rate down; up to
    :data:`~tracker.core.timewarp.MIN_SPEED`'s inverse (10) times the source's rate."""
    fps = check_fps(fps, "target frame rate", source)
    step = source_fps / fps
    if step < MIN_SPEED * (1 - 1e-9):
        raise InputError(f"cannot resample from {source_fps:g} Hz up to {fps:g} Hz: at most {1 / MIN_SPEED:g} "
                         f"times the file's rate ({source_fps / MIN_SPEED:g} Hz)", source)
    n = warped_length(n_frames, step) if n_frames > 1 else 1
    times = np.arange(n) * step
    whole = np.round(times)
    return np.where(np.abs(times - whole) < 1e-6, whole, np.minimum(times, n_frames - 1))


def marker_positions(clip: MocapClip, roles=MARKER_NAMES + EXTRA_POINT_NAMES) -> np.ndarray:
    """Positions ``T x M x 3`` (mm) of the named roles (default: 15 markers then the 4 extra fit points), by
    the clip's :class:`~data_tools.motion.skeleton_points.PointPlan` (its naming convention or joint map).

    Raises :class:`InputError` naming the clip's file when its names are not recognised.
    """
    return clip.point_plan().positions(clip.positions, roles)
