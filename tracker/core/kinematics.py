"""Batched forward kinematics: poses ``(..., D)`` -> link frames, segment frames, named points.

Convention: world frame z up, millimetres; ``R_world_from_link`` maps link
coordinates to world coordinates (column vectors), ``origin`` is the link's
joint centre in world coordinates. Any leading batch shape is kept. The link
frames come from one loop over the poses compiled with numba (measured 5x
faster than batched numpy products over the tree's depth levels: 0.32 against
1.64 ms for 256 poses of the bodytrack model, 4.8 against 34 ms for 4000).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numba import njit

from tracker.core.body import BALL, EULER, FREE, BodyModel
from tracker.core.rotations import exp_map_into, exp_map_to_matrix


@dataclass
class Kinematics:
    """Result of :func:`forward_kinematics` for poses of batch shape ``B``.

    ``rotations`` ``B x L x 3 x 3`` (world from link), ``origins`` ``B x L x 3``
    (joint centres, mm), ``points`` ``B x M x 3`` (the model's named points, mm).
    """

    model: BodyModel
    rotations: np.ndarray
    origins: np.ndarray

    @cached_property
    def points(self) -> np.ndarray:
        """The model's named points ``B x M x 3`` (mm), computed on first use (the likelihood needs none)."""
        t = _tables(self.model)
        link = t["point_link"]
        rotated = np.einsum("...ij,...j->...i", self.rotations[..., link, :, :], t["point_pos"])
        return rotated + self.origins[..., link, :]

    @property
    def markers(self) -> np.ndarray:
        """The marker set ``B x 15 x 3`` (mm), in the model's marker order."""
        return self.points[..., self.model.marker_indices, :]

    def segment_frames(self) -> np.ndarray:
        """Segment frames ``B x S x 4 x 4``, world from segment.

        Segment axes: x along the cross-section's width (radius r), y along its
        depth (radius r * depth_scale), z along the cone axis; origin at the
        centre of the proximal end. A point at fraction s in [0, 1] of the cone,
        angle phi, has segment coordinates ``(r(s) cos phi, r(s) d sin phi, s L)``.
        """
        R, o = self.segment_rotations()
        out = np.zeros(R.shape[:-2] + (4, 4))
        out[..., :3, :3] = R
        out[..., :3, 3] = o
        out[..., 3, 3] = 1.0
        return out

    def segment_rotations(self) -> tuple[np.ndarray, np.ndarray]:
        """The segment frames of :meth:`segment_frames` as rotations ``B x S x 3 x 3`` (world from segment) and
        origins ``B x S x 3`` (mm)."""
        tables = _tables(self.model)
        link, in_link = tables["seg_link"], tables["seg_in_link"]
        batch = self.rotations.shape[:-3]
        R = np.ascontiguousarray(self.rotations.reshape((-1,) + self.rotations.shape[-3:]))
        out = np.empty((len(R), len(link), 3, 3))
        _segment_rotations(R, link, in_link, out)
        return out.reshape(batch + out.shape[1:]), self.origins[..., link, :]


def segment_tables(model: BodyModel) -> tuple[np.ndarray, np.ndarray]:
    """Each segment's link ``(S,)`` (int64) and its frame's rotation in that link's ``S x 3 x 3``: segment ``s``
    has rotation ``R_link[link[s]] @ in_link[s]`` and origin at its link's joint centre."""
    tables = _tables(model)
    return tables["seg_link"], tables["seg_in_link"]


def _tables(model: BodyModel) -> dict:
    """Index tables derived once per model (cached on the model)."""
    cache = model._cache
    if "fk_tables" in cache:
        return cache["fk_tables"]
    links = model.links
    n = len(links)
    if links[0].parent != -1 or links[0].joint != FREE:
        raise ValueError(f"{model.name}: link 0 must be the free root")
    for i, link in enumerate(links[1:], start=1):
        if not 0 <= link.parent < i:
            raise ValueError(f"{model.name}: link {link.name} must come after its parent")
    ball = [i for i, link in enumerate(links) if link.joint == BALL]
    root = links[0]
    root_euler = bool(root.axes)
    if len(root.dofs) != (3 + len(root.axes) if root_euler else 6):
        raise ValueError(f"{model.name}: the root needs 3 position dofs and an exp map or one angle per axis")
    euler_factors = []  # (link index, dof index, axis) for every single-axis factor, in order
    for i, link in enumerate(links):
        if link.joint == EULER or (i == 0 and root_euler):
            dofs = link.dofs[3:] if i == 0 else link.dofs
            if len(link.axes) != len(dofs) or not link.axes:
                raise ValueError(f"{model.name}: euler link {link.name} needs one axis per dof")
            for dof, axis in zip(dofs, link.axes):
                euler_factors.append((i, dof, np.asarray(axis, float)))
    fixed = np.array([np.eye(3) if link.rotation is None else np.asarray(link.rotation, float) for link in links])
    if np.abs(fixed @ np.swapaxes(fixed, -1, -2) - np.eye(3)).max() > 1e-9 or np.any(np.linalg.det(fixed) < 0):
        raise ValueError(f"{model.name}: every fixed link rotation must be a rotation matrix")
    # The compiled kernel's description of every link (see _fk_kernel).
    kind = np.zeros(n, np.int64)
    n_factors = np.zeros(n, np.int64)
    most = max([3] + [sum(1 for f in euler_factors if f[0] == i) for i in range(n)])
    dofs = np.zeros((n, most), np.int64)
    axes = np.zeros((n, most, 3))
    if not root_euler:
        kind[0], dofs[0, :3] = 1, root.dofs[3:6]
    for i in ball:
        kind[i], dofs[i, :3] = 1, links[i].dofs
    for i, dof, axis in euler_factors:
        kind[i] = 2
        dofs[i, n_factors[i]], axes[i, n_factors[i]] = dof, axis
        n_factors[i] += 1
    has_fixed = np.array([link.rotation is not None and not np.array_equal(fixed[i], np.eye(3))
                          for i, link in enumerate(links)])
    tables = {
        "kernel": (kind, dofs, n_factors, axes, fixed, has_fixed, np.array([link.parent for link in links], np.int64),
                   np.array([link.offset for link in links], float), np.array(root.dofs[:3], np.int64)),
        "parents": np.array([link.parent for link in links]),
        "offsets": np.array([link.offset for link in links], float),
        "root_dofs": np.array(links[0].dofs),
        "root_euler": root_euler,
        "fixed": fixed,
        "has_fixed": any(link.rotation is not None for link in links),
        "ball_links": np.array(ball, int),
        "ball_dofs": np.array([links[i].dofs for i in ball], int).reshape(-1, 3),
        "euler_links": np.array([f[0] for f in euler_factors], int),
        "euler_dofs": np.array([f[1] for f in euler_factors], int),
        "euler_axes": np.array([f[2] for f in euler_factors], float).reshape(-1, 3),
        "point_link": np.array([p.link for p in model.points], int),
        "point_pos": np.array([p.position for p in model.points], float),
        "seg_link": np.array([s.link for s in model.segments], np.int64),
        "seg_in_link": np.array([s.frame_in_link() for s in model.segments], float),
    }
    cache["fk_tables"] = tables
    return tables


@njit(cache=True, nogil=True)
def _matmul3(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@njit(cache=True, nogil=True)
def _segment_rotations(R: np.ndarray, link: np.ndarray, in_link: np.ndarray, out: np.ndarray) -> None:
    """``out[b, s] = R[b, link[s]] @ in_link[s]`` for link rotations ``R`` ``B x L x 3 x 3``."""
    for b in range(R.shape[0]):
        for s in range(link.shape[0]):
            _matmul3(R[b, link[s]], in_link[s], out[b, s])


@njit(cache=True, nogil=True)
def _fk_kernel(poses, kind, dofs, n_factors, axes, fixed, has_fixed, parents, offsets, root_dofs, R, o):
    """World rotations ``R`` ``B x L x 3 x 3`` and joint centres ``o`` ``B x L x 3`` (mm) of poses ``B x D``,
    filled in place one pose at a time. Link ``l``'s joint rotation is the identity (``kind`` 0), the exp map
    of dofs ``dofs[l, :3]`` (1), or the product, left to right, of ``n_factors[l]`` rotations by dof
    ``dofs[l, k]`` about ``axes[l, k]`` (2); then its fixed rotation on the left where ``has_fixed``.
    Links come after their parents."""
    local = np.empty((3, 3))
    factor = np.empty((3, 3))
    tmp = np.empty((3, 3))
    for p in range(poses.shape[0]):
        for link in range(kind.shape[0]):
            if kind[link] == 0:
                for i in range(3):
                    for j in range(3):
                        local[i, j] = 1.0 if i == j else 0.0
            elif kind[link] == 1:
                exp_map_into(poses[p, dofs[link, 0]], poses[p, dofs[link, 1]], poses[p, dofs[link, 2]], local)
            else:
                for k in range(n_factors[link]):
                    angle = poses[p, dofs[link, k]]
                    exp_map_into(angle * axes[link, k, 0], angle * axes[link, k, 1], angle * axes[link, k, 2],
                             factor if k else local)
                    if k:
                        _matmul3(local, factor, tmp)
                        local[:, :] = tmp
            if has_fixed[link]:
                _matmul3(fixed[link], local, tmp)
                local[:, :] = tmp
            if link == 0:
                R[p, 0] = local
                for i in range(3):
                    o[p, 0, i] = poses[p, root_dofs[i]] + offsets[0, i]
            else:
                parent = parents[link]
                _matmul3(R[p, parent], local, R[p, link])
                for i in range(3):
                    o[p, link, i] = o[p, parent, i] + (R[p, parent, i, 0] * offsets[link, 0]
                                                       + R[p, parent, i, 1] * offsets[link, 1]
                                                       + R[p, parent, i, 2] * offsets[link, 2])


def forward_kinematics(model: BodyModel, poses: np.ndarray) -> Kinematics:
    """Forward kinematics of ``poses`` ``(..., D)`` (D = ``model.n_dofs``), one compiled loop over the poses.

    No input checks (this is a hot path): callers at public boundaries use
    :meth:`BodyModel.check_poses`.
    """
    poses = np.asarray(poses, dtype=float)
    t = _tables(model)
    batch = poses.shape[:-1]
    n = len(model.links)
    flat = np.ascontiguousarray(poses.reshape(-1, poses.shape[-1]))
    R = np.empty((len(flat), n, 3, 3))
    o = np.empty((len(flat), n, 3))
    _fk_kernel(flat, *t["kernel"], R, o)
    return Kinematics(model=model, rotations=R.reshape(batch + (n, 3, 3)), origins=o.reshape(batch + (n, 3)))


def markers(model: BodyModel, poses: np.ndarray) -> np.ndarray:
    """The model's markers ``(..., 15, 3)`` in mm for poses ``(..., D)``."""
    return forward_kinematics(model, poses).markers


def _left_jacobian(v: np.ndarray) -> np.ndarray:
    """Left Jacobian of SO(3) at exp maps ``(..., 3)`` -> ``(..., 3, 3)``.

    ``d/dt exp(v + t u) = [J(v) u]_x exp(v)``; series expansion below 1e-4 rad.
    """
    t2 = np.einsum("...i,...i->...", v, v)
    t = np.sqrt(t2)
    small = t < 1e-4
    ts = np.where(small, 1.0, t)
    a = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(ts)) / (ts * ts))
    b = np.where(small, 1.0 / 6.0 - t2 / 120.0, (ts - np.sin(ts)) / (ts ** 3))
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def _jacobian_tables(model: BodyModel) -> dict:
    cache = model._cache
    if "jac_tables" in cache:
        return cache["jac_tables"]
    links = model.links
    D = model.n_dofs
    dof_link = np.full(D, -1)
    for i, link in enumerate(links):
        for d in link.dofs:
            dof_link[d] = i
    ancestors = []
    for i in range(len(links)):
        chain, j = set(), i
        while j >= 0:
            chain.add(j)
            j = links[j].parent
        ancestors.append(chain)
    point_links = [p.link for p in model.points]
    mask = np.array([[dof_link[d] in ancestors[pl] for d in range(D)] for pl in point_links], float)
    cache["jac_tables"] = {"dof_link": dof_link, "mask": mask}
    return cache["jac_tables"]


def point_jacobians(model: BodyModel, poses: np.ndarray, fk: Kinematics | None = None,
                    points: np.ndarray | None = None) -> np.ndarray:
    """Derivatives of every named point (or of the named points ``points``, indices ``(M,)``) with respect to
    every pose number: ``B x M x 3 x D``.

    Analytic: a rotational dof with world axis ``w`` about joint centre ``o``
    moves a downstream point ``p`` at ``w x (p - o)`` (mm per radian); root
    position dofs move every point one-for-one. Exp-map joints get their axes
    from the SO(3) left Jacobian.
    """
    poses = np.asarray(poses, float)
    fk = fk or forward_kinematics(model, poses)
    t = _tables(model)
    jt = _jacobian_tables(model)
    batch = poses.shape[:-1]
    D = model.n_dofs
    axes = np.zeros(batch + (D, 3))
    pivots = np.zeros(batch + (D, 3))
    R, o = fk.rotations, fk.origins
    rd = t["root_dofs"]
    # Frame each joint rotates in: its parent's world rotation times the fixed
    # rotation (the world, possibly rotated, for the root).
    parents = t["parents"]
    parent_R = np.concatenate([np.broadcast_to(np.eye(3), batch + (1, 3, 3)), R[..., parents[1:], :, :]], axis=-3)
    if t["has_fixed"]:
        parent_R = parent_R @ t["fixed"]
    if not t["root_euler"]:
        axes[..., rd[3:6], :] = np.swapaxes(parent_R[..., 0, :, :] @ _left_jacobian(poses[..., rd[3:6]]), -1, -2)
        pivots[..., rd[3:6], :] = o[..., 0, None, :]
    if len(t["ball_links"]):
        bl = t["ball_links"]
        Jl = _left_jacobian(poses[..., t["ball_dofs"]])  # B x nb x 3 x 3
        w = parent_R[..., bl, :, :] @ Jl  # columns are the world axes of the 3 dofs
        axes[..., t["ball_dofs"], :] = np.swapaxes(w, -1, -2)
        pivots[..., t["ball_dofs"], :] = o[..., bl, None, :]
    if len(t["euler_links"]):
        el, ed, ea = t["euler_links"], t["euler_dofs"], t["euler_axes"]
        pre = parent_R[..., el, :, :].copy()  # rotation before each factor: parent @ fixed @ earlier factors
        factors = exp_map_to_matrix(poses[..., ed, None] * ea)
        for j in range(1, len(el)):
            if el[j] == el[j - 1]:
                pre[..., j, :, :] = pre[..., j - 1, :, :] @ factors[..., j - 1, :, :]
        axes[..., ed, :] = np.einsum("...jab,jb->...ja", pre, ea)
        pivots[..., ed, :] = o[..., el, :]
    pts, mask = fk.points, jt["mask"]
    if points is not None:
        pts, mask = pts[..., points, :], mask[points]
    # B x M x D x 3
    J = np.cross(axes[..., None, :, :], pts[..., :, None, :] - pivots[..., None, :, :])
    J *= mask[..., None]
    J[..., rd[0:3], :] = np.eye(3)
    return np.swapaxes(J, -1, -2)


def standing_height(model: BodyModel) -> float:
    """Stature (mm): height of the head marker in the rest pose, which stands on z = 0."""
    fk = forward_kinematics(model, model.rest_pose())
    return float(fk.points[model.point_index("head"), 2])
