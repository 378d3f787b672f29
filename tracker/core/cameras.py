"""Calibrated cameras: pinhole with Bouguet / OpenCV distortion, batched projection, built-in rigs (file formats live in
:mod:`data_tools.sequences.calibration`).

Convention
----------
``R``, ``t`` map world to camera, ``X_cam = R @ X_world + t`` (mm); camera axes
x right, y down, z forward (OpenCV). Normalised coordinates ``(x, y) = (X/Z, Y/Z)``
are distorted by ``dist = [k1, k2, p1, p2, k3]``:
``r2 = x^2 + y^2``, ``radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3``,
``xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)``, ``yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y``,
then pixels ``u = fx (xd + skew yd) + cx``, ``v = fy yd + cy``. ``skew`` is
Bouguet's dimensionless ``alpha_c``. Pixel ``(x, y)`` = ``(u, v)`` has its
origin at the centre of the top-left pixel; images are ``H x W``.
Bouguet's ``kc(1..5)`` is the same vector as OpenCV's ``[k1, k2, p1, p2, k3]``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from tracker.core.arrays import device, namespace
from tracker.core.errors import InputError


@dataclass(frozen=True)
class Camera:
    """One calibrated camera. Intrinsics in pixels, extrinsics world-to-camera in mm."""

    name: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    skew: float
    dist: tuple[float, float, float, float, float]
    R: np.ndarray
    t: np.ndarray

    @property
    def centre(self) -> np.ndarray:
        """Camera centre in world coordinates (3,), mm."""
        return -self.R.T @ self.t

    def points_in_camera(self, points_world: np.ndarray) -> np.ndarray:
        """``(..., 3)`` world points (mm) -> camera coordinates (mm)."""
        return np.asarray(points_world, float) @ self.R.T + self.t

    def project(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels ``(..., 2)`` and depths ``(..., )`` (mm along the optical axis) of world points ``(..., 3)``."""
        X = np.asarray(points_world, float)
        pix, depth = CameraRig([self]).project(X.reshape(-1, 3))
        return pix[0].reshape(X.shape[:-1] + (2,)), depth[0].reshape(X.shape[:-1])

    def to_dict(self) -> dict:
        return {"name": self.name, "width": int(self.width), "height": int(self.height), "fx": float(self.fx),
                "fy": float(self.fy), "cx": float(self.cx), "cy": float(self.cy), "skew": float(self.skew),
                "dist": [float(d) for d in self.dist], "R": np.asarray(self.R, float).tolist(),
                "t": np.asarray(self.t, float).tolist()}


def make_camera(name: str, width: int, height: int, fx: float, fy: float, cx: float, cy: float, R,
                t, skew: float = 0.0, dist: Sequence[float] = (0, 0, 0, 0, 0), source: str | None = None) -> Camera:
    """Build a :class:`Camera`, checking every value; errors name ``source`` (a file) when given."""
    label = f"camera {name!r}"
    try:
        width_i, height_i = int(width), int(height)
    except (TypeError, ValueError):
        raise InputError(f"{label}: width and height must be integers, got {width!r}, {height!r}", source) from None
    if width_i <= 0 or height_i <= 0 or width_i != width or height_i != height:
        raise InputError(f"{label}: width and height must be positive integers, got {width}, {height}", source)
    vals = {"fx": fx, "fy": fy, "cx": cx, "cy": cy, "skew": skew}
    for k, v in vals.items():
        try:
            vals[k] = float(v)
        except (TypeError, ValueError):
            raise InputError(f"{label}: {k} must be a number, got {v!r}", source) from None
        if not np.isfinite(vals[k]):
            raise InputError(f"{label}: {k} must be finite, got {v}", source)
    if vals["fx"] <= 0 or vals["fy"] <= 0:
        raise InputError(f"{label}: focal lengths must be positive, got fx={fx}, fy={fy}", source)
    try:
        d = np.asarray(dist, float).ravel()
        R = np.asarray(R, float)
        t = np.asarray(t, float).ravel()
    except (TypeError, ValueError):
        raise InputError(f"{label}: dist, R and t must be numbers", source) from None
    if d.size > 5:
        raise InputError(f"{label}: dist has {d.size} coefficients; this model takes at most 5 "
                         "[k1, k2, p1, p2, k3]", source)
    d = np.concatenate([d, np.zeros(5 - d.size)])
    if not np.all(np.isfinite(d)):
        raise InputError(f"{label}: dist contains NaN or infinite values", source)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise InputError(f"{label}: R must be a finite 3x3 matrix, got shape {R.shape}", source)
    orth = np.abs(R @ R.T - np.eye(3)).max()
    det = np.linalg.det(R)
    if orth > 1e-5 or abs(det - 1.0) > 1e-5:
        raise InputError(f"{label}: R is not a rotation (max |R R^T - I| = {orth:.3g}, det = {det:.6g})", source)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise InputError(f"{label}: t must be 3 finite numbers (mm), got {t.tolist()}", source)
    return Camera(name=str(name), width=width_i, height=height_i, fx=vals["fx"], fy=vals["fy"], cx=vals["cx"],
                  cy=vals["cy"], skew=vals["skew"], dist=tuple(float(x) for x in d), R=R, t=t)


class CameraRig:
    """V cameras with their parameters stacked for batched projection."""

    def __init__(self, cameras: Sequence[Camera]):
        if not cameras:
            raise InputError("a camera rig needs at least one camera")
        self.cameras = list(cameras)
        self.R = np.stack([c.R for c in cameras])  # V x 3 x 3
        self.t = np.stack([c.t for c in cameras])  # V x 3
        self.focal = np.array([[c.fx, c.fy] for c in cameras])  # V x 2
        self.principal = np.array([[c.cx, c.cy] for c in cameras])  # V x 2
        self.skew = np.array([c.skew for c in cameras])  # V
        self.dist = np.array([c.dist for c in cameras])  # V x 5
        self.has_distortion = bool(np.any(self.dist != 0))

    def __len__(self) -> int:
        return len(self.cameras)

    def __getitem__(self, i: int) -> Camera:
        return self.cameras[i]

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.cameras]

    def subset(self, views: Sequence[int]) -> "CameraRig":
        """The rig of the cameras at indices ``views``."""
        bad = [v for v in views if not 0 <= v < len(self)]
        if bad:
            raise InputError(f"view indices {bad} out of range: this rig has {len(self)} cameras (0..{len(self) - 1})")
        return CameraRig([self.cameras[v] for v in views])

    def project(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points ``(..., K, 3)`` (mm) into every view.

        Returns pixels ``(..., V, K, 2)`` and depths ``(..., V, K)`` (mm; points
        behind a camera have depth <= 0 and meaningless pixels, callers mask them).
        """
        X = np.asarray(points_world, float)
        # (..., 1, K, 3) @ (V, 3, 3)^T -> (..., V, K, 3)
        Xc = np.einsum("vij,...kj->...vki", self.R, X) + self.t[:, None, :]
        return self.camera_to_pixels(Xc)

    def frames_in_cameras(self, rotations, origins, dtype=None):
        """Frames (rotations ``B... x 3 x 3`` world from frame, origins ``B... x 3`` mm, any batch shape ``B``)
        in every camera's coordinates, components leading: axes ``3 x 3 x V x B...`` (``[k, i]``: component
        ``i`` of axis ``k``) and origins ``3 x V x B...``, as ``dtype`` (a dtype of the inputs' array library;
        default the rotations' own), one matrix product each. numpy arrays or torch tensors on any device."""
        xp, dev = namespace(rotations), device(rotations)
        dtype = rotations.dtype if dtype is None else dtype
        batch = tuple(rotations.shape[:-2])
        V = len(self)
        cam = xp.asarray(self.R.transpose(1, 0, 2).reshape(3 * V, 3), dtype=dtype, device=dev)  # rows (i, v)
        rot = xp.permute_dims(xp.reshape(rotations, (-1, 3, 3)), (2, 1, 0))  # k, j, batch
        # numpy's matmul is faster on a contiguous stack: one copy converts and lays it out.
        rot = np.ascontiguousarray(rot, dtype=dtype) if xp is np else xp.astype(rot, dtype)
        axes = xp.matmul(cam, rot)  # k x (i v) x batch
        org = xp.matmul(cam, xp.permute_dims(xp.reshape(xp.astype(origins, dtype), (-1, 3)), (1, 0)))
        org = org + xp.asarray(self.t.T.reshape(3 * V, 1), dtype=dtype, device=dev)
        return xp.reshape(axes, (3, 3, V) + batch), xp.reshape(org, (3, V) + batch)

    def camera_to_pixels(self, Xc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Camera coordinates ``(..., V, K, 3)`` (mm, view ``v`` in camera ``v``) -> pixels and depths."""
        x, y, z = (np.moveaxis(Xc[..., i], -2, 0) for i in range(3))
        u, v = self.pixels(x, y, z)
        return np.stack([np.moveaxis(u, 0, -2), np.moveaxis(v, 0, -2)], axis=-1), Xc[..., 2]

    def pixels(self, x, y, z):
        """Pixel coordinates ``(u, v)`` of camera coordinates given as components ``x, y, z`` ``V x ...`` (mm, view
        ``v`` in camera ``v``), in their dtype (float32 or float64; numpy arrays or torch tensors on any device).
        Points behind a camera (``z <= 0``) get meaningless pixels; callers mask them."""
        xp, dev = namespace(z), device(z)
        if not xp.isdtype(z.dtype, "real floating"):
            x, y, z = (xp.astype(a, xp.float64) for a in (x, y, z))
        shape = (len(self),) + (1,) * (z.ndim - 1)

        def per_view(values: np.ndarray):
            return xp.reshape(xp.asarray(values, dtype=z.dtype, device=dev), shape)

        z_safe = xp.where(xp.abs(z) < 1e-9, 1e-9, z)
        x = x / z_safe
        y = y / z_safe
        if self.has_distortion:
            k1, k2, p1, p2, k3 = (per_view(self.dist[:, i]) for i in range(5))
            r2 = x * x + y * y
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            xy = x * y
            xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
            yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
        else:
            xd, yd = x, y
        fx, fy, cx, cy = (per_view(a) for a in (self.focal[:, 0], self.focal[:, 1], self.principal[:, 0],
                                                 self.principal[:, 1]))
        u = fx * (xd + per_view(self.skew) * yd) + cx
        return u, fy * yd + cy


# ---------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------

# ---------------------------------------------------------------------------
# Built-in rigs
# ---------------------------------------------------------------------------

def look_at(name: str, position, target, width: int = 640, height: int = 480, focal: float = 600.0,
            up=(0.0, 0.0, 1.0)) -> Camera:
    """A distortion-free camera at ``position`` (mm) looking at ``target`` (mm), image up along world ``up``.

    The principal point is the image centre, ``((W-1)/2, (H-1)/2)`` in the
    pixel-centre convention.
    """
    position = np.asarray(position, float)
    z = np.asarray(target, float) - position
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    if np.linalg.norm(x) < 1e-9:
        raise InputError(f"camera {name!r}: viewing direction is parallel to the up vector")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    return make_camera(name, width, height, focal, focal, (width - 1) / 2.0, (height - 1) / 2.0, R, -R @ position)


def default_rig(views: int = 4, width: int = 640, height: int = 480, radius: float = 6000.0,
                camera_height: float = 2000.0, target_height: float = 1000.0, focal: float = 600.0) -> CameraRig:
    """``views`` cameras evenly spaced on a circle around a 4 m x 4 m capture area.

    Cameras stand ``radius`` mm from the centre (on the diagonals when
    ``views = 4``), ``camera_height`` mm up, each looking at the point
    ``target_height`` mm above the centre. At the defaults (measured, see
    tests/core/test_cameras.py) every point of the central 3 m x 3 m from the floor
    to 1.9 m is in every view, 99.9% of the full 4 m x 4 m area is, and a
    1.75 m person at the centre is about 170 pixels tall.
    """
    if views < 1:
        raise InputError(f"a rig needs at least one view, got {views}")
    cams = []
    for i in range(views):
        a = np.pi / 4 + 2 * np.pi * i / views
        pos = (radius * np.cos(a), radius * np.sin(a), camera_height)
        cams.append(look_at(f"cam{i}", pos, (0.0, 0.0, target_height), width, height, focal))
    return CameraRig(cams)


def monocular_rig(width: int = 640, height: int = 480) -> CameraRig:
    """One camera of :func:`default_rig` (the first, on a diagonal, 6 m away), for monocular tracking."""
    return default_rig(1, width, height)
