"""The CPU path of the edge + silhouette likelihood: one compiled loop from link frames to mean costs.

For every view, particle and cone it takes the cone's frame into the camera, solves for the two occluding
contour lines, projects their four end points (with the lens distortion), forms the sample points as fixed
affine combinations of the corners and reads the nearest pixel of the cost maps (a point off the image costs
1): the same steps and formulas as the array-API path of
:meth:`likelihoods.edge_silhouette.EdgeSilhouetteLikelihood.array_costs` (``frames_in_cameras``,
``contour_corners``, ``pixels``, a matrix product with the sample weights, ``flat_index``, means), which runs
them as whole-array operations on a GPU. Here they run in float64 inside one loop that releases the
interpreter lock for its whole duration, so that threads scoring blocks of particles run in parallel (array
steps between compiled ones would hold the lock: two threads then reach 1.4 times one thread's speed, not 2).
A test (``tests/likelihoods/test_compiled_costs.py``) pins the two paths to the same costs on random poses and on
real frames.

Shapes: link rotations ``p x L x 3 x 3`` (world from link), link origins ``p x L x 3`` (mm), outputs
``p x V``; cameras ``V``; cones ``S``; sample points per cone ``N`` (the first ``n_contour`` on the contours).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from tracker.core.body import BodyModel
from tracker.core.cameras import CameraRig
from tracker.core.cones import segment_table
from tracker.core.kinematics import Kinematics, segment_tables


@dataclass(frozen=True)
class ConeCostTables:
    """What the compiled loop needs of a body model, a camera rig and the sample pattern (float64 arrays).

    ``seg_link`` ``(S,)`` and ``seg_in_link`` ``S x 3 x 3``: each cone's link and its frame in the link's;
    ``cone`` ``S x 4``: length, depth scale, proximal and distal radius (mm); ``camera_R`` ``V x 3 x 3`` and
    ``camera_t`` ``V x 3`` (world to camera, mm); ``intrinsics`` ``V x 5``: fx, fy, cx, cy, skew (pixels);
    ``distortion`` ``V x 5`` ``[k1, k2, p1, p2, k3]``; ``weights`` ``4 x N``: each sample point's weights on the
    corners (line 0 proximal, distal, line 1 proximal, distal).
    """

    seg_link: np.ndarray
    seg_in_link: np.ndarray
    cone: np.ndarray
    camera_R: np.ndarray
    camera_t: np.ndarray
    intrinsics: np.ndarray
    distortion: np.ndarray
    has_distortion: bool
    weights: np.ndarray

    def __post_init__(self) -> None:
        """The shapes and dtypes the compiled loop reads without bounds checks."""
        S, V = len(self.seg_link), len(self.camera_R)
        shapes = {"seg_link": (S,), "seg_in_link": (S, 3, 3), "cone": (S, 4), "camera_R": (V, 3, 3),
                  "camera_t": (V, 3), "intrinsics": (V, 5), "distortion": (V, 5)}
        for name, shape in shapes.items():
            a = getattr(self, name)
            if a.shape != shape or a.dtype != (np.int64 if name == "seg_link" else np.float64):
                raise ValueError(f"cone cost tables: {name} is {a.dtype} {a.shape}, expected "
                                 f"{'int64' if name == 'seg_link' else 'float64'} {shape}")
        if self.weights.ndim != 2 or self.weights.shape[0] != 4 or self.weights.dtype != np.float64:
            raise ValueError(f"cone cost tables: weights are {self.weights.dtype} {self.weights.shape}, expected "
                             "float64 4 x N")

    @classmethod
    def of(cls, model: BodyModel, rig: CameraRig, weights: np.ndarray) -> "ConeCostTables":
        link, in_link = segment_tables(model)
        t = segment_table(model)
        cone = np.stack([t["length"], t["depth"], t["r0"], t["r1"]], axis=1)
        intrinsics = np.concatenate([rig.focal, rig.principal, rig.skew[:, None]], axis=1)
        return cls(np.ascontiguousarray(link, np.int64), np.ascontiguousarray(in_link, float),
                   np.ascontiguousarray(cone, float), np.ascontiguousarray(rig.R, float),
                   np.ascontiguousarray(rig.t, float), np.ascontiguousarray(intrinsics, float),
                   np.ascontiguousarray(rig.dist, float), rig.has_distortion,
                   np.ascontiguousarray(weights, float))


def cone_costs(kinematics: Kinematics, tables: ConeCostTables, edge_map: np.ndarray, silhouette_map: np.ndarray,
               view_offset: np.ndarray, height: int, width: int, n_contour: int,
               edge_out: np.ndarray, silhouette_out: np.ndarray,
               corners_out: tuple[np.ndarray, np.ndarray] | None = None,
               ellipses_out: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Mean edge and silhouette costs of every particle in every view, written into ``edge_out`` and
    ``silhouette_out`` (float64, ``p x V``).

    ``kinematics``: the particles' link frames (:func:`tracker.core.kinematics.forward_kinematics` of ``p``
    poses). ``edge_map`` and ``silhouette_map`` (float32, flat) are the views' cost maps of ``height x width``
    pixels each, one after the other (view ``k`` starts at ``view_offset[k]``). A point reads its nearest pixel;
    a point off the image (or one that is not a number) costs 1, and so do all the points of a cone with a
    corner at or behind a camera's plane (as the array path's maps padded with cost 1 give). ``corners_out``,
    when given, receives the corners' pixels ``(u, v)``, each float64 ``V x p x S x 4`` (those of a cone behind
    the camera set to -1e6), and ``ellipses_out`` (given with it) the pixels of the cones' end ellipses
    (:func:`tracker.core.cones.end_ellipse_points`), each float64 ``V x p x S x 6``, -1e6 alike and where one of
    the six points is at or behind the camera's plane. The shapes and
    dtypes are checked here: the compiled loop reads and writes without bounds checks.
    """
    R, o = kinematics.rotations, kinematics.origins
    if R.ndim != 4 or R.shape[1:] != (o.shape[1], 3, 3) or o.shape != R.shape[:2] + (3,):
        raise ValueError(f"cone costs: link frames of shapes {R.shape} and {o.shape}, expected p x L x 3 x 3 "
                         "and p x L x 3")
    P, L = o.shape[:2]
    V, S, N = len(tables.camera_R), len(tables.seg_link), tables.weights.shape[1]
    size = V * height * width
    floats = (R, o, edge_map, silhouette_map, edge_out, silhouette_out)
    if not (all(a.dtype == np.float64 for a in (R, o, edge_out, silhouette_out))
            and edge_map.dtype == silhouette_map.dtype == np.float32 and view_offset.dtype.kind in "iu"):
        raise ValueError("cone costs: frames and outputs must be float64, maps float32, offsets integers "
                         f"(got {[a.dtype.name for a in floats]}, {view_offset.dtype.name})")
    if corners_out is None:
        u_out = v_out = np.empty((0, 0, 0, 4))
    else:
        u_out, v_out = corners_out
        if u_out.shape != (V, P, S, 4) or v_out.shape != (V, P, S, 4) or not u_out.dtype == v_out.dtype == float:
            raise ValueError(f"cone costs: corner outputs of shapes {u_out.shape} and {v_out.shape}, expected "
                             f"float64 {(V, P, S, 4)}")
    if ellipses_out is None:
        eu_out = ev_out = np.empty((0, 0, 0, 6))
    else:
        eu_out, ev_out = ellipses_out
        if (corners_out is None or eu_out.shape != (V, P, S, 6) or ev_out.shape != (V, P, S, 6)
                or not eu_out.dtype == ev_out.dtype == float):
            raise ValueError(f"cone costs: ellipse outputs of shapes {eu_out.shape} and {ev_out.shape}, expected "
                             f"float64 {(V, P, S, 6)} beside the corners'")
    if (not 0 < n_contour < N or view_offset.shape != (V,) or height < 1 or width < 1
            or height * width >= 2**31
            or edge_out.shape != (P, V) or silhouette_out.shape != (P, V)
            or edge_map.shape != (size,) or silhouette_map.shape != (size,)
            or (S and not 0 <= tables.seg_link.min() <= tables.seg_link.max() < L)
            or (V and not 0 <= view_offset.min() <= view_offset.max() <= size - height * width)):
        raise ValueError(f"cone costs: inconsistent shapes (frames of {L} links for cones on links up to "
                         f"{tables.seg_link.max(initial=-1)}, maps {edge_map.shape} and {silhouette_map.shape} "
                         f"for {V} views of {height} x {width}, offsets {view_offset.shape}, outputs "
                         f"{edge_out.shape} and {silhouette_out.shape}, {n_contour} contour points of {N})")
    _cone_costs(np.ascontiguousarray(R), np.ascontiguousarray(o), tables.seg_link, tables.seg_in_link, tables.cone,
                tables.camera_R, tables.camera_t, tables.intrinsics, tables.distortion, tables.has_distortion,
                tables.weights, edge_map, silhouette_map, view_offset, height, width, n_contour, edge_out,
                silhouette_out, u_out, v_out, eu_out, ev_out)


@njit(inline="always")
def _pixel(X, Y, Z, fx, fy, cx, cy, skew, k1, k2, p1, p2, k3, has_distortion):
    """The pixel ``(u, v)`` of camera coordinates ``X, Y, Z`` (mm): :meth:`tracker.core.cameras.CameraRig.pixels`
    for one point."""
    iz = 1.0 / (1e-9 if abs(Z) < 1e-9 else Z)
    x, y = X * iz, Y * iz
    if has_distortion:
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xy = x * y
        xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
    else:
        xd, yd = x, y
    return fx * (xd + skew * yd) + cx, fy * yd + cy


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _cone_costs(R, o, seg_link, seg_in_link, cone, camera_R, camera_t, intrinsics, distortion, has_distortion,
                weights, edge_map, silhouette_map, view_offset, height, width, n_contour, edge_out,
                silhouette_out, u_out, v_out, eu_out, ev_out):
    """:func:`cone_costs`'s loop over views, particles and cones: the array path's formulas one scalar at a time
    (:func:`tracker.core.cones.contour_corners`, :meth:`tracker.core.cameras.CameraRig.pixels`,
    :meth:`likelihoods.edge_silhouette._CostMaps.flat_index`). A cone's sample points get their pixel indices
    in one loop (-1 off the image), then the maps are read in another: twice as fast as one loop doing both, as
    the first compiles to vector instructions. Products and sums may fuse into one rounding (``contract``:
    9% faster, differences of 1e-16 in a pixel coordinate); no other fast-math liberty is taken, so a point
    that is not a number still costs 1."""
    P = R.shape[0]
    V, S, N = camera_R.shape[0], seg_link.shape[0], weights.shape[1]
    keep_corners = u_out.shape[0] > 0
    keep_ellipses = eu_out.shape[0] > 0
    x_end, y_end = float(width), float(height)
    row = np.int32(width)
    n_edge, n_sil = S * n_contour, S * (N - n_contour)
    w0, w1, w2, w3 = weights[0].copy(), weights[1].copy(), weights[2].copy(), weights[3].copy()
    seg = np.empty((P, S, 3, 3))  # the cones' rotations, world from cone: the link's times the cone's in the link
    for p in range(P):
        for s in range(S):
            link = seg_link[s]
            for i in range(3):
                for j in range(3):
                    seg[p, s, i, j] = (R[p, link, i, 0] * seg_in_link[s, 0, j] + R[p, link, i, 1] * seg_in_link[s, 1, j]
                                       + R[p, link, i, 2] * seg_in_link[s, 2, j])
    cu = np.empty(4)  # the corners' pixels
    cv = np.empty(4)
    index = np.empty(N, np.int32)  # the sample points' pixels in the view's maps
    for k in range(V):
        offset = view_offset[k]
        fx, fy, cx, cy, skew = intrinsics[k, 0], intrinsics[k, 1], intrinsics[k, 2], intrinsics[k, 3], intrinsics[k, 4]
        k1, k2, p1, p2, k3 = distortion[k, 0], distortion[k, 1], distortion[k, 2], distortion[k, 3], distortion[k, 4]
        c00, c01, c02 = camera_R[k, 0, 0], camera_R[k, 0, 1], camera_R[k, 0, 2]
        c10, c11, c12 = camera_R[k, 1, 0], camera_R[k, 1, 1], camera_R[k, 1, 2]
        c20, c21, c22 = camera_R[k, 2, 0], camera_R[k, 2, 1], camera_R[k, 2, 2]
        t0, t1, t2 = camera_t[k, 0], camera_t[k, 1], camera_t[k, 2]
        for p in range(P):
            edge_sum, sil_sum = 0.0, 0.0
            for s in range(S):
                link = seg_link[s]
                g = seg[p, s]
                # The cone's axes in the camera (a{axis}{component}; axes width, depth, cone axis) and its origin.
                a00 = c00 * g[0, 0] + c01 * g[1, 0] + c02 * g[2, 0]
                a01 = c10 * g[0, 0] + c11 * g[1, 0] + c12 * g[2, 0]
                a02 = c20 * g[0, 0] + c21 * g[1, 0] + c22 * g[2, 0]
                a10 = c00 * g[0, 1] + c01 * g[1, 1] + c02 * g[2, 1]
                a11 = c10 * g[0, 1] + c11 * g[1, 1] + c12 * g[2, 1]
                a12 = c20 * g[0, 1] + c21 * g[1, 1] + c22 * g[2, 1]
                a20 = c00 * g[0, 2] + c01 * g[1, 2] + c02 * g[2, 2]
                a21 = c10 * g[0, 2] + c11 * g[1, 2] + c12 * g[2, 2]
                a22 = c20 * g[0, 2] + c21 * g[1, 2] + c22 * g[2, 2]
                ox, oy, oz = o[p, link, 0], o[p, link, 1], o[p, link, 2]
                o0 = (c00 * ox + c01 * oy + c02 * oz) + t0
                o1 = (c10 * ox + c11 * oy + c12 * oz) + t1
                o2 = (c20 * ox + c21 * oy + c22 * oz) + t2
                # The camera centre in cone coordinates and the contour lines' angles.
                length, depth, r0, r1 = cone[s, 0], cone[s, 1], cone[s, 2], cone[s, 3]
                ccx = -(a00 * o0 + a01 * o1 + a02 * o2)
                ccy = -(a10 * o0 + a11 * o1 + a12 * o2)
                ccz = -(a20 * o0 + a21 * o1 + a22 * o2)
                A = (depth * length) * ccx
                B = length * ccy
                C = depth * (length * r0 + (r1 - r0) * ccz)
                norm = np.sqrt(A * A + B * B)
                inv = 1.0 / max(norm, 1e-12)
                cos_b = A * inv if norm > 0 else 1.0
                sin_b = B * inv
                ratio = min(max(C * inv, -1.0), 1.0)
                if abs(C) < norm:
                    cos_h, sin_h = ratio, np.sqrt(1.0 - ratio * ratio)
                else:  # no ruling is a contour: the widest pair across the view direction
                    cos_h, sin_h = 0.0, 1.0
                behind = False
                for c in range(4):  # line 0 proximal, distal; line 1 proximal, distal
                    sign = -1.0 if c < 2 else 1.0
                    cos_p = cos_b * cos_h - sign * (sin_b * sin_h)
                    dsin_p = depth * (sin_b * cos_h + sign * (cos_b * sin_h))
                    rad0 = cos_p * a00 + dsin_p * a10
                    rad1 = cos_p * a01 + dsin_p * a11
                    rad2 = cos_p * a02 + dsin_p * a12
                    if c % 2 == 0:
                        X, Y, Z = o0 + r0 * rad0, o1 + r0 * rad1, o2 + r0 * rad2
                    else:
                        X = o0 + length * a20 + r1 * rad0
                        Y = o1 + length * a21 + r1 * rad1
                        Z = o2 + length * a22 + r1 * rad2
                    if Z <= 0:
                        behind = True
                    cu[c], cv[c] = _pixel(X, Y, Z, fx, fy, cx, cy, skew, k1, k2, p1, p2, k3, has_distortion)
                if keep_corners:
                    for c in range(4):
                        u_out[k, p, s, c] = -1e6 if behind else cu[c]
                        v_out[k, p, s, c] = -1e6 if behind else cv[c]
                if keep_ellipses:  # each end's centre, then its ends of the width and the depth semi-axes
                    ends_behind = behind  # (an end cut by the camera's plane covers nothing either)
                    for end in range(2):
                        along, r = (0.0, r0) if end == 0 else (length, r1)
                        X0, Y0, Z0 = o0 + along * a20, o1 + along * a21, o2 + along * a22
                        for e, (dx, dy, dz) in enumerate(((0.0, 0.0, 0.0), (r * a00, r * a01, r * a02),
                                                          (r * depth * a10, r * depth * a11, r * depth * a12))):
                            ends_behind = ends_behind or Z0 + dz <= 0
                            eu_out[k, p, s, 3 * end + e], ev_out[k, p, s, 3 * end + e] = _pixel(
                                X0 + dx, Y0 + dy, Z0 + dz, fx, fy, cx, cy, skew, k1, k2, p1, p2, k3, has_distortion)
                    if ends_behind:
                        eu_out[k, p, s, :] = -1e6
                        ev_out[k, p, s, :] = -1e6
                if behind:  # every point reads the border: cost 1
                    edge_sum += n_contour
                    sil_sum += N - n_contour
                    continue
                for n in range(N):
                    px = (cu[0] * w0[n] + cu[1] * w1[n] + cu[2] * w2[n] + cu[3] * w3[n]) + 0.5
                    py = (cv[0] * w0[n] + cv[1] * w1[n] + cv[2] * w2[n] + cv[3] * w3[n]) + 0.5
                    on = (px >= 0.0) & (px < x_end) & (py >= 0.0) & (py < y_end)  # False for NaN too
                    index[n] = np.int32(py) * row + np.int32(px) if on else -1
                for n in range(n_contour):
                    edge_sum += edge_map[offset + index[n]] if index[n] >= 0 else 1.0
                for n in range(n_contour, N):
                    sil_sum += silhouette_map[offset + index[n]] if index[n] >= 0 else 1.0
            edge_out[p, k] = edge_sum / n_edge
            silhouette_out[p, k] = sil_sum / n_sil


def uncovered_fraction(u: np.ndarray, v: np.ndarray, eu: np.ndarray, ev: np.ndarray, foreground: list,
                       out: np.ndarray) -> None:
    """The CPU path of the bidirectional term: the fraction of each view's sampled foreground pixels outside
    every projected cone, written into ``out`` (float64 ``p x V``).

    ``u``, ``v`` (float64 ``V x p x S x 4``): the cones' contour corners in pixels; ``eu``, ``ev`` (float64
    ``V x p x S x 6``): their end ellipses' centres and semi-axis ends in pixels; ``foreground``: per view the
    sampled pixels ``F x 2`` ``(x, y)``. The same test as the array path's
    (:func:`likelihoods.edge_silhouette._uncovered`), a pixel at a time, stopping at the first cone that covers it.
    """
    V, p, S = u.shape[:3]
    if (v.shape != u.shape or u.shape[3:] != (4,) or eu.shape != (V, p, S, 6) or ev.shape != eu.shape
            or out.shape != (p, V) or len(foreground) != V
            or not u.dtype == v.dtype == eu.dtype == ev.dtype == out.dtype == np.float64):
        raise ValueError(f"uncovered fraction: corners {u.shape} and {v.shape}, ellipses {eu.shape} and {ev.shape}, "
                         f"{len(foreground)} foreground samples, output {out.shape}: expected float64 V x p x S x 4, "
                         "V x p x S x 6, V samples and p x V")
    counts = np.array([len(f) for f in foreground], np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    points = (np.concatenate([np.asarray(f, np.float64).reshape(-1, 2) for f in foreground]) if V
              else np.zeros((0, 2)))
    _uncovered_fraction(np.ascontiguousarray(u), np.ascontiguousarray(v), np.ascontiguousarray(eu),
                        np.ascontiguousarray(ev), points, offsets, out)


@njit(inline="always")
def _end_ellipse(eu, ev, k, p, s, end):
    """Centre ``(cx, cy)`` and conjugate semi-axes ``(ax, ay)``, ``(bx, by)`` (pixels) of the end ellipse whose
    points start at ``end`` (0 proximal, 3 distal) in :func:`uncovered_fraction`'s ``eu``, ``ev``."""
    cx, cy = eu[k, p, s, end], ev[k, p, s, end]
    return (cx, cy, eu[k, p, s, end + 1] - cx, ev[k, p, s, end + 1] - cy,
            eu[k, p, s, end + 2] - cx, ev[k, p, s, end + 2] - cy)


@njit(cache=True, nogil=True, error_model="numpy")
def _uncovered_fraction(u, v, eu, ev, points, offsets, out):
    """:func:`uncovered_fraction`'s loop over views, particles, pixels and cones. Each cone's outline gets a
    bounding box first, so that a pixel far from a cone costs four comparisons."""
    V, P, S = u.shape[0], u.shape[1], u.shape[2]
    qx = np.empty((S, 4))  # the quadrilateral line 0 proximal, distal, line 1 distal, proximal
    qy = np.empty((S, 4))
    box = np.empty((S, 4))  # x min, x max, y min, y max of the cone's outline
    for k in range(V):
        start, stop = offsets[k], offsets[k + 1]
        if stop == start:
            for p in range(P):
                out[p, k] = 0.0
            continue
        for p in range(P):
            for s in range(S):
                for c, corner in enumerate((0, 1, 3, 2)):
                    qx[s, c], qy[s, c] = u[k, p, s, corner], v[k, p, s, corner]
                x0, x1 = min(qx[s, 0], qx[s, 1], qx[s, 2], qx[s, 3]), max(qx[s, 0], qx[s, 1], qx[s, 2], qx[s, 3])
                y0, y1 = min(qy[s, 0], qy[s, 1], qy[s, 2], qy[s, 3]), max(qy[s, 0], qy[s, 1], qy[s, 2], qy[s, 3])
                for end in (0, 3):  # an ellipse with conjugate semi-axes a, b reaches sqrt(a_x^2 + b_x^2) across
                    cx, cy, ax, ay, bx, by = _end_ellipse(eu, ev, k, p, s, end)
                    rx, ry = np.sqrt(ax * ax + bx * bx), np.sqrt(ay * ay + by * by)
                    x0, x1 = min(x0, cx - rx), max(x1, cx + rx)
                    y0, y1 = min(y0, cy - ry), max(y1, cy + ry)
                box[s, 0], box[s, 1], box[s, 2], box[s, 3] = x0, x1, y0, y1
            hits = 0
            for n in range(start, stop):
                x, y = points[n, 0], points[n, 1]
                covered = False
                for s in range(S):
                    if not (box[s, 0] <= x <= box[s, 1] and box[s, 2] <= y <= box[s, 3]):
                        continue
                    positive, negative = True, True
                    for c in range(4):
                        d = (c + 1) % 4
                        cross = (qx[s, d] - qx[s, c]) * (y - qy[s, c]) - (qy[s, d] - qy[s, c]) * (x - qx[s, c])
                        positive = positive and cross > 0.0
                        negative = negative and cross < 0.0
                    if positive or negative:
                        covered = True
                        break
                    for end in (0, 3):
                        cx, cy, ax, ay, bx, by = _end_ellipse(eu, ev, k, p, s, end)
                        det = ax * by - ay * bx
                        dx, dy = x - cx, y - cy
                        alpha, beta = dx * by - dy * bx, ax * dy - ay * dx
                        if alpha * alpha + beta * beta < det * det:
                            covered = True
                            break
                    if covered:
                        break
                if covered:
                    hits += 1
            out[p, k] = 1.0 - hits / (stop - start)  # as the array path computes it, to the last bit
