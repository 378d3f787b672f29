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


def contour_angles(model: BodyModel, frames: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Angles ``phi`` ``(..., V, S, 2)`` of the two occluding-contour lines of every cone seen from each centre.

    ``frames`` ``(..., S, 4, 4)`` segment frames; ``centres`` ``V x 3`` camera
    centres (mm, world). A ruling at angle ``phi`` of the cone is a contour
    line when the tangent plane along it contains the camera centre ``c``
    (segment coordinates): ``A cos phi + B sin phi = C`` with ``A = d L c_x``,
    ``B = L c_y``, ``C = d (L r0 + (r1 - r0) c_z)``. When no ruling qualifies
    (a camera looking down the cone's axis) the widest pair across the view
    direction is used.
    """
    t = segment_table(model)
    R = frames[..., None, :, :3, :3]  # ... 1 S 3 3
    rel = centres[:, None, :] - frames[..., None, :, :3, 3]  # ... V S 3
    # Centre in segment coordinates, R^T rel, written out (small arrays; einsum is slower here).
    cx = R[..., 0, 0] * rel[..., 0] + R[..., 1, 0] * rel[..., 1] + R[..., 2, 0] * rel[..., 2]
    cy = R[..., 0, 1] * rel[..., 0] + R[..., 1, 1] * rel[..., 1] + R[..., 2, 1] * rel[..., 2]
    cz = R[..., 0, 2] * rel[..., 0] + R[..., 1, 2] * rel[..., 1] + R[..., 2, 2] * rel[..., 2]
    L, d, r0, dr = t["length"], t["depth"], t["r0"], t["r1"] - t["r0"]
    A = d * L * cx
    B = L * cy
    C = d * (L * r0 + dr * cz)
    base = np.arctan2(B, A)
    norm = np.sqrt(A * A + B * B)
    ratio = np.clip(C / np.maximum(norm, 1e-12), -1.0, 1.0)
    half = np.where(np.abs(C) < norm, np.arccos(ratio), np.pi / 2)
    return np.stack([base - half, base + half], axis=-1)


def contour_endpoints(model: BodyModel, frames: np.ndarray, angles: np.ndarray,
                      dtype: type = np.float64) -> np.ndarray:
    """World end points ``(..., V, S, 2, 2, 3)`` (line, proximal/distal end, xyz; mm) of the contour lines at
    ``angles`` ``(..., V, S, 2)``, as ``dtype``. Each contour line is a straight ruling of the cone between
    them: ``o + s L u_z + r(s) (cos phi u_x + d sin phi u_y)`` for ``s`` = 0, 1."""
    t = segment_table(model)
    R = frames[..., :3, :3].astype(dtype)
    o = frames[..., :3, 3].astype(dtype)
    cos = np.cos(angles).astype(dtype)[..., None]  # ... V S 2 1
    dsin = (np.sin(angles) * t["depth"][:, None]).astype(dtype)[..., None]
    radial = cos * R[..., None, :, None, :, 0] + dsin * R[..., None, :, None, :, 1]  # ... V S 2 3
    ends = np.stack([o, o + t["length"].astype(dtype)[:, None] * R[..., :, 2]], axis=-2)  # ... S 2 3
    r = np.stack([t["r0"], t["r1"]], axis=-1).astype(dtype)  # S x 2
    return ends[..., None, :, None, :, :] + r[:, None, :, None] * radial[..., :, :, None, :]
