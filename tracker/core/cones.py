"""Points on and inside a body model's truncated cones, batched over poses.

A segment (see :class:`tracker.core.body.Segment`) is a truncated cone with an
elliptical cross-section. In its segment frame (``Kinematics.segment_frames``:
x = width, y = depth, z = axis, origin at the proximal end) the point at axial
fraction ``s`` in [0, 1], angle ``phi`` and radial fraction ``rho`` in [0, 1] is
``(rho r(s) cos phi, rho r(s) d sin phi, s L)`` with ``r(s) = r0 + s (r1 - r0)``.
All lengths are millimetres.
"""
from __future__ import annotations

import numpy as np

from tracker.core.arrays import device, namespace
from tracker.core.body import BodyModel


def segment_table(model: BodyModel) -> dict[str, np.ndarray]:
    """Per-segment ``(S,)`` arrays: ``length``, ``r0`` (proximal radius), ``r1`` (distal), ``depth`` scale."""
    cache = model._cache
    if "segment_table" not in cache:
        segs = model.segments
        cache["segment_table"] = {
            "length": np.array([s.length for s in segs], float),
            "r0": np.array([s.radius_proximal for s in segs], float),
            "r1": np.array([s.radius_distal for s in segs], float),
            "depth": np.array([s.depth_scale for s in segs], float),
        }
    return cache["segment_table"]


def cone_points(model: BodyModel, frames: np.ndarray, s: np.ndarray, phi: np.ndarray,
                rho: np.ndarray | float = 1.0) -> np.ndarray:
    """World points ``(..., S, K, 3)`` (mm) at cone coordinates ``s``, ``phi``, ``rho`` (each ``(K,)`` or scalar).

    ``frames`` ``(..., S, 4, 4)``: segment frames from
    :meth:`tracker.core.kinematics.Kinematics.segment_frames`.
    """
    t = segment_table(model)
    s, phi, rho = np.broadcast_arrays(np.asarray(s, float), np.asarray(phi, float), np.asarray(rho, float))
    r = (t["r0"][:, None] + s[None, :] * (t["r1"] - t["r0"])[:, None]) * rho[None, :]  # S x K
    local = np.stack([r * np.cos(phi)[None, :], r * t["depth"][:, None] * np.sin(phi)[None, :],
                      s[None, :] * t["length"][:, None]], axis=-1)  # S x K x 3
    return np.einsum("...sij,skj->...ski", frames[..., :3, :3], local) + frames[..., None, :3, 3]


def surface_grid(n_along: int, n_around: int) -> tuple[np.ndarray, np.ndarray]:
    """Cone coordinates ``(s, phi)``, each ``(n_along * n_around,)``, of rings from end to end."""
    s = np.linspace(0.0, 1.0, n_along)
    phi = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    S, P = np.meshgrid(s, phi, indexing="ij")
    return S.ravel(), P.ravel()


def volume_grid(n_along: int, n_around: int, radial: tuple[float, ...] = (0.0, 0.5)) -> tuple[np.ndarray, ...]:
    """Cone coordinates ``(s, phi, rho)`` of points strictly inside a cone.

    Axial fractions are the centres of ``n_along`` equal slices; each radial
    fraction in ``radial`` below 1 gets ``n_around`` angles (one point on the
    axis for 0).
    """
    s_vals = (np.arange(n_along) + 0.5) / n_along
    s_list, phi_list, rho_list = [], [], []
    for rho in radial:
        if not 0.0 <= rho < 1.0:
            raise ValueError(f"radial fractions must lie in [0, 1), got {rho}")
        phis = np.array([0.0]) if rho == 0.0 else np.linspace(0, 2 * np.pi, n_around, endpoint=False)
        S, P = np.meshgrid(s_vals, phis, indexing="ij")
        s_list.append(S.ravel())
        phi_list.append(P.ravel())
        rho_list.append(np.full(S.size, rho))
    return np.concatenate(s_list), np.concatenate(phi_list), np.concatenate(rho_list)


def contour_corners(model: BodyModel, axes: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """End points of the two occluding-contour lines of every cone, seen from a camera at the origin.

    Coordinates are the camera's (mm), components on the leading axis so that every elementwise step runs
    over long contiguous arrays: ``axes`` ``3 x 3 x B... x S`` (``axes[k, i]``: component ``i`` of the
    segment's axis ``k`` -- width, depth, cone axis), ``origins`` ``3 x B... x S`` (the segments' proximal
    centres), any batch shape ``B``, in the dtype of the result: numpy arrays, or torch tensors on any device
    (the likelihood's array path, written against the array API through ``array_api_compat``; its CPU path
    runs the same formulas in :mod:`likelihoods.compiled_costs`). Returns ``3 x B... x S x 4``: the corners
    line 0 proximal, line 0 distal, line 1 proximal, line 1 distal.

    A ruling at angle ``phi`` is a contour line when the tangent plane along it contains the camera centre
    ``c`` (segment coordinates): ``A cos phi + B sin phi = C`` with ``A = d L c_x``, ``B = L c_y``,
    ``C = d (L r0 + (r1 - r0) c_z)``, so ``phi = atan2(B, A) -+ acos(C / |(A, B)|)``, evaluated through the
    cosines and sines of the two angles (no trigonometric calls). When no ruling qualifies (a camera looking
    down the cone's axis) the widest pair across the view direction is used. Each contour line is a
    straight ruling ``o + s L u_z + r(s) (cos phi u_x + d sin phi u_y)``, ``s`` = 0 and 1.
    """
    t = segment_table(model)
    xp, dev = namespace(origins), device(origins)
    L, d, r0, r1 = (xp.asarray(t[k], dtype=origins.dtype, device=dev) for k in ("length", "depth", "r0", "r1"))
    # The camera centre in segment coordinates: -axes^T @ origin.
    cx, cy, cz = (-(axes[k, 0] * origins[0] + axes[k, 1] * origins[1] + axes[k, 2] * origins[2]) for k in range(3))
    A = (d * L) * cx
    B = L * cy
    C = d * (L * r0 + (r1 - r0) * cz)
    norm = xp.sqrt(A * A + B * B)
    inv = 1.0 / xp.maximum(norm, 1e-12)
    cos_b = xp.where(norm > 0, A * inv, 1.0)  # atan2(0, 0) = 0
    sin_b = B * inv
    ratio = xp.clip(C * inv, -1.0, 1.0)
    seen = xp.abs(C) < norm
    cos_h = xp.where(seen, ratio, 0.0)  # half the angle between the lines: acos(ratio), else pi / 2
    sin_h = xp.where(seen, xp.sqrt(1.0 - ratio * ratio), 1.0)
    out = xp.empty(tuple(origins.shape) + (4,), dtype=origins.dtype, device=dev)
    for line, sign in ((0, -1.0), (1, 1.0)):  # phi = base - half, base + half
        cos_p = cos_b * cos_h - sign * (sin_b * sin_h)
        dsin_p = d * (sin_b * cos_h + sign * (cos_b * sin_h))
        for i in range(3):
            radial = cos_p * axes[0, i] + dsin_p * axes[1, i]
            out[i, ..., 2 * line] = origins[i] + r0 * radial
            out[i, ..., 2 * line + 1] = origins[i] + L * axes[2, i] + r1 * radial
    return out


def end_ellipse_points(model: BodyModel, axes, origins):
    """Points that span the projections of every cone's two end ellipses, seen from a camera at the origin.

    ``axes`` ``3 x 3 x B... x S`` and ``origins`` ``3 x B... x S`` as for :func:`contour_corners` (camera
    coordinates, mm). Returns ``3 x B... x S x 6``: for the proximal end its centre, the centre plus the width
    semi-axis and the centre plus the depth semi-axis, then the same for the distal end. Projected, each triple
    gives the end's image as an ellipse: the affine image of the end about its centre, which leaves out the
    change of perspective across the end, about ``f r^2 / Z^2`` pixels (focal length ``f`` px, radius ``r`` and
    depth ``Z`` mm; half a pixel for a 60 mm end 2 m away at ``f`` = 600, a few pixels for a torso's end).
    """
    t = segment_table(model)
    xp, dev = namespace(origins), device(origins)
    L, d, r0, r1 = (xp.asarray(t[k], dtype=origins.dtype, device=dev) for k in ("length", "depth", "r0", "r1"))
    out = xp.empty(tuple(origins.shape) + (6,), dtype=origins.dtype, device=dev)
    for i in range(3):
        distal = origins[i] + L * axes[2, i]
        for end, (centre, r) in enumerate(((origins[i], r0), (distal, r1))):
            out[i, ..., 3 * end] = centre
            out[i, ..., 3 * end + 1] = centre + r * axes[0, i]
            out[i, ..., 3 * end + 2] = centre + (r * d) * axes[1, i]
    return out
