"""Forward kinematics on torch tensors, for the likelihood's device path (``--device cuda``).

The same computation as :mod:`tracker.core.kinematics` (whose compiled loop over poses is the CPU path:
measured faster there than any batched form), written for a device that wants few, large kernels: local
joint rotations for every link at once (one Rodrigues formula over all exp-map joints, one over all
fixed-axis factors), then the tree composed one depth level at a time (the 15-cone model has 5 levels), the
3 x 3 products as broadcast multiply-adds (:func:`small_matmul`, five elementwise kernels each): a fixed
number of kernels whatever the batch. Both read the same index tables (``kinematics._tables``), and
``tests/likelihoods/test_torch_path.py`` checks that they agree to float precision.

Shapes: poses ``B x D`` (mm, radians); results ``B x S x 3 x 3`` (segment rotations, world from segment)
and ``B x S x 3`` (segment origins, mm) in the poses' dtype and device.
"""
from __future__ import annotations

import numpy as np
import torch

from tracker.core.body import BodyModel
from tracker.core.kinematics import _tables


def exp_map_to_matrix_torch(v: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``(..., 3, 3)`` of exponential maps ``(..., 3)`` (Rodrigues; the Taylor series below
    ``1e-6`` rad, as :func:`tracker.core.rotations.exp_map_to_matrix`)."""
    x, y, z = v.unbind(-1)
    t2 = x * x + y * y + z * z
    small = t2 < 1e-12
    t = torch.sqrt(torch.where(small, torch.ones_like(t2), t2))
    a = torch.where(small, 1.0 - t2 / 6.0, torch.sin(t) / t)
    b = torch.where(small, 0.5 - t2 / 24.0, (1.0 - torch.cos(t)) / (t * t))
    bxy, bxz, byz = b * x * y, b * x * z, b * y * z
    rows = (1.0 - b * (y * y + z * z), bxy - a * z, bxz + a * y,
            bxy + a * z, 1.0 - b * (x * x + z * z), byz - a * x,
            bxz - a * y, byz + a * x, 1.0 - b * (x * x + y * y))
    return torch.stack(rows, dim=-1).reshape(v.shape[:-1] + (3, 3))


def small_matmul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``a @ b`` for stacks of small matrices ``(..., n, k) @ (..., k, m)`` (broadcast batch dimensions), as
    ``k`` broadcast multiply-adds. A GPU's batched matrix product is made for large matrices: on an H100 it
    took half the likelihood's device time on these 3 x 3 products (``docs/reference/performance.md``, "GPU path")."""
    if a.shape[-1] != b.shape[-2] or a.dtype != b.dtype:
        raise ValueError(f"small_matmul: {tuple(a.shape)} {a.dtype} @ {tuple(b.shape)} {b.dtype} do not multiply")
    out = a[..., :, 0:1] * b[..., 0:1, :]
    for j in range(1, a.shape[-1]):
        out = out + a[..., :, j:j + 1] * b[..., j:j + 1, :]
    return out


class TorchKinematics:
    """A body model's kinematic tree as index tensors on one device, in one dtype; call it on poses.

    Built once per (model, device, dtype) by :func:`torch_kinematics`.
    """

    def __init__(self, model: BodyModel, device: torch.device, dtype: torch.dtype):
        t = _tables(model)
        kind, dofs, n_factors, axes, fixed, has_fixed, parents, offsets, root_dofs = t["kernel"]
        self.device, self.dtype = device, dtype
        n = len(kind)

        def tensor(a, dt=dtype):
            return torch.as_tensor(np.asarray(a), dtype=dt, device=device)

        def index(a):
            return torch.as_tensor(np.asarray(a, np.int64), device=device)

        self.n_links = n
        self.exp_links = index(np.flatnonzero(kind == 1))
        self.exp_dofs = index(dofs[kind == 1, :3])  # n_exp x 3
        # Every fixed-axis factor, grouped by its position k in its link's product (applied left to right).
        self.factor_steps = []
        for k in range(int(n_factors.max(initial=0))):
            links = np.flatnonzero((kind == 2) & (n_factors > k))
            self.factor_steps.append((index(links), index(dofs[links, k]), tensor(axes[links, k])))
        self.fixed_links = index(np.flatnonzero(has_fixed))
        self.fixed = tensor(fixed[has_fixed])
        self.root_dofs = index(root_dofs)
        self.root_offset = tensor(offsets[0])
        depth = np.zeros(n, np.int64)
        for link in range(1, n):
            depth[link] = depth[parents[link]] + 1
        self.levels = [(index(np.flatnonzero(depth == d)), index(parents[depth == d]), tensor(offsets[depth == d]))
                       for d in range(1, int(depth.max(initial=0)) + 1)]
        self.seg_link = index(t["seg_link"])
        self.seg_in_link = tensor(t["seg_in_link"])

    def local_rotations(self, poses: torch.Tensor) -> torch.Tensor:
        """Each link's joint rotation (its fixed rotation on the left) ``B x L x 3 x 3``."""
        B = poses.shape[0]
        local = torch.eye(3, dtype=self.dtype, device=self.device).expand(B, self.n_links, 3, 3).clone()
        if len(self.exp_links):
            local[:, self.exp_links] = exp_map_to_matrix_torch(poses[:, self.exp_dofs])
        for k, (links, dofs, axes) in enumerate(self.factor_steps):
            factor = exp_map_to_matrix_torch(poses[:, dofs, None] * axes)  # B x n x 3 x 3
            local[:, links] = factor if k == 0 else small_matmul(local[:, links], factor)
        if len(self.fixed_links):
            local[:, self.fixed_links] = small_matmul(self.fixed, local[:, self.fixed_links])
        return local

    def links(self, poses: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """World rotations ``B x L x 3 x 3`` (world from link) and joint centres ``B x L x 3`` (mm)."""
        poses = poses.to(self.device, self.dtype)
        R = self.local_rotations(poses)  # the root's world rotation is its local one
        o = torch.empty(R.shape[:2] + (3,), dtype=self.dtype, device=self.device)
        o[:, 0] = poses[:, self.root_dofs] + self.root_offset
        for links, parents, offsets in self.levels:
            parent_R = R[:, parents]
            R[:, links] = small_matmul(parent_R, R[:, links])
            o[:, links] = o[:, parents] + small_matmul(parent_R, offsets[..., None])[..., 0]
        return R, o

    def __call__(self, poses: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Segment rotations ``B x S x 3 x 3`` (world from segment) and origins ``B x S x 3`` (mm) of poses
        ``B x D``, as :meth:`tracker.core.kinematics.Kinematics.segment_rotations`."""
        R, o = self.links(poses)
        return small_matmul(R[:, self.seg_link], self.seg_in_link), o[:, self.seg_link]


def torch_kinematics(model: BodyModel, device: str | torch.device, dtype: torch.dtype = torch.float64
                     ) -> TorchKinematics:
    """The model's :class:`TorchKinematics` on ``device`` in ``dtype`` (cached on the model)."""
    device = torch.device(device)
    key = ("torch_kinematics", str(device), dtype)
    cache = model._cache
    if key not in cache:
        cache[key] = TorchKinematics(model, device, dtype)
    return cache[key]
