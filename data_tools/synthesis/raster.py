"""A small z-buffered triangle rasteriser in numpy (no Python loop over triangles or pixels).

Triangles are given by projected vertices (pixels, ``(x, y)`` with the origin
at the centre of the top-left pixel) and their depths (mm along the optical
axis). A pixel belongs to a triangle when its centre lies inside it. Depth and
attributes are interpolated perspective-correctly (``1/z`` is affine in the
image). Lens distortion is ignored inside a triangle, which is exact for the
distortion-free synthetic cameras and a sub-pixel approximation for small
triangles otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NEAR_MM = 10.0


@dataclass
class Fragments:
    """The visible fragment of every covered pixel: ``M`` pixels.

    ``pixel`` ``(M,)`` flat index ``y * W + x``; ``face`` ``(M,)`` triangle
    index; ``bary`` ``M x 3`` perspective-correct barycentric weights;
    ``depth`` ``(M,)`` mm.
    """

    pixel: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    depth: np.ndarray


def rasterize(pix: np.ndarray, depth: np.ndarray, faces: np.ndarray, width: int, height: int,
              zbuffer: np.ndarray | None = None, front: np.ndarray | None = None) -> Fragments:
    """Nearest visible fragment per pixel of the triangles ``faces`` ``F x 3`` (vertex indices).

    ``pix`` ``N x 2`` and ``depth`` ``(N,)`` are the projected vertices.
    ``zbuffer`` ``H x W`` (mm) hides fragments at or behind it (the scene
    already drawn). ``front`` ``(F,)`` boolean selects the triangles to draw
    (e.g. front faces); triangles with a vertex closer than 10 mm are dropped.
    """
    faces = np.asarray(faces)
    keep = np.all(depth[faces] > NEAR_MM, axis=1)
    if front is not None:
        keep &= front
    face_ids = np.flatnonzero(keep)
    tri = pix[faces[face_ids]]  # F x 3 x 2
    z = depth[faces[face_ids]]  # F x 3
    x0, y0 = tri[:, 0, 0], tri[:, 0, 1]
    x1, y1 = tri[:, 1, 0], tri[:, 1, 1]
    x2, y2 = tri[:, 2, 0], tri[:, 2, 1]
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    xmin = np.clip(np.ceil(tri[..., 0].min(1)), 0, width - 1).astype(np.int64)
    xmax = np.clip(np.floor(tri[..., 0].max(1)), 0, width - 1).astype(np.int64)
    ymin = np.clip(np.ceil(tri[..., 1].min(1)), 0, height - 1).astype(np.int64)
    ymax = np.clip(np.floor(tri[..., 1].max(1)), 0, height - 1).astype(np.int64)
    inside_img = (tri[..., 0].max(1) >= 0) & (tri[..., 0].min(1) <= width - 1) & \
                 (tri[..., 1].max(1) >= 0) & (tri[..., 1].min(1) <= height - 1)
    w = np.where(inside_img, xmax - xmin + 1, 0)
    h = np.where(inside_img, ymax - ymin + 1, 0)
    ok = (np.abs(area) > 1e-12) & (w > 0) & (h > 0)
    sel = np.flatnonzero(ok)
    counts = (w * h)[sel]
    total = int(counts.sum())
    empty = Fragments(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0))
    if total == 0:
        return empty
    rep = np.repeat(sel, counts)
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    local = np.arange(total) - starts
    px = xmin[rep] + local % w[rep]
    py = ymin[rep] + local // w[rep]
    fx, fy = px.astype(float), py.astype(float)
    inv_area = 1.0 / area[rep]
    b0 = ((x1[rep] - fx) * (y2[rep] - fy) - (x2[rep] - fx) * (y1[rep] - fy)) * inv_area
    b1 = ((x2[rep] - fx) * (y0[rep] - fy) - (x0[rep] - fx) * (y2[rep] - fy)) * inv_area
    b2 = 1.0 - b0 - b1
    eps = -1e-9
    inside = (b0 >= eps) & (b1 >= eps) & (b2 >= eps)
    rep, px, py, b0, b1, b2 = rep[inside], px[inside], py[inside], b0[inside], b1[inside], b2[inside]
    iz = 1.0 / z[rep]
    w0, w1, w2 = b0 * iz[:, 0], b1 * iz[:, 1], b2 * iz[:, 2]
    inv_depth = w0 + w1 + w2
    frag_depth = 1.0 / inv_depth
    pixel = py * width + px
    if zbuffer is not None:
        front_of_scene = frag_depth < zbuffer.reshape(-1)[pixel]
        rep, pixel, frag_depth = rep[front_of_scene], pixel[front_of_scene], frag_depth[front_of_scene]
        w0, w1, w2, inv_depth = (a[front_of_scene] for a in (w0, w1, w2, inv_depth))
    if pixel.size == 0:
        return empty
    order = np.lexsort((frag_depth, pixel))
    first = np.ones(order.size, bool)
    first[1:] = pixel[order[1:]] != pixel[order[:-1]]
    win = order[first]
    bary = np.stack([w0[win], w1[win], w2[win]], axis=1) / inv_depth[win, None]
    return Fragments(pixel=pixel[win], face=face_ids[rep[win]], bary=bary, depth=frag_depth[win])
