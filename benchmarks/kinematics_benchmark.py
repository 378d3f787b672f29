"""Forward kinematics speed for P poses (default 1000): numpy (the implementation) vs a torch transcription.

Run by hand:  python benchmarks/kinematics_benchmark.py [--particles 1000] [--repeats 200]

The torch version below transcribes tracker.core.kinematics.forward_kinematics step by step (same level-by-level
batched products) so the two can be compared on this machine; it is kept here only as the measured
alternative. It is checked against the numpy result before timing.
"""
from __future__ import annotations

import argparse

import numpy as np
import torch

from tracker.core.body import fifteen_cone_model
from tracker.core.kinematics import _tables, forward_kinematics

from timing import mean_ms


def torch_fk(model, poses: torch.Tensor):
    t = _tables(model)

    def expmap(v):
        th = v.norm(dim=-1, keepdim=True).clamp_min(1e-12)
        k = v / th
        K = torch.zeros(v.shape[:-1] + (3, 3), dtype=v.dtype)
        K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
        K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = k[..., 2], -k[..., 1], k[..., 0]
        s, c = torch.sin(th)[..., None], torch.cos(th)[..., None]
        return torch.eye(3, dtype=v.dtype) + s * K + (1 - c) * (K @ K)

    B, n = poses.shape[0], len(model.links)
    local = torch.eye(3, dtype=poses.dtype).expand(B, n, 3, 3).clone()
    rd = torch.as_tensor(t["root_dofs"])
    local[:, 0] = expmap(poses[:, rd[3:6]])
    local[:, t["ball_links"]] = expmap(poses[:, torch.as_tensor(t["ball_dofs"])])
    el = t["euler_links"]
    fac = expmap(poses[:, torch.as_tensor(t["euler_dofs"]), None] * torch.as_tensor(t["euler_axes"], dtype=poses.dtype))
    first = np.ones(len(el), bool)
    first[1:] = el[1:] != el[:-1]
    local[:, el[first]] = fac[:, torch.as_tensor(first)]
    for j in np.flatnonzero(~first):
        local[:, el[j]] = local[:, el[j]] @ fac[:, j]
    R = torch.empty(B, n, 3, 3, dtype=poses.dtype)
    o = torch.empty(B, n, 3, dtype=poses.dtype)
    R[:, 0] = local[:, 0]
    o[:, 0] = poses[:, rd[:3]]
    off = torch.as_tensor(t["offsets"], dtype=poses.dtype)
    par = t["parents"]
    for level in t["levels"]:
        Rp = R[:, par[level]]
        R[:, level] = Rp @ local[:, level]
        o[:, level] = o[:, par[level]] + (Rp @ off[level][..., None])[..., 0]
    pl = t["point_link"]
    pts = (R[:, pl] @ torch.as_tensor(t["point_pos"], dtype=poses.dtype)[..., None])[..., 0] + o[:, pl]
    return R, o, pts


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=200)
    args = ap.parse_args()
    model = fifteen_cone_model()
    rng = np.random.default_rng(0)
    q = model.rest_pose() + rng.normal(size=(args.particles, 40)) * 0.3
    qt = torch.as_tensor(q)
    ref = forward_kinematics(model, q).points
    assert np.allclose(torch_fk(model, qt)[2].numpy(), ref, atol=1e-9)
    print(f"P = {args.particles}, {torch.get_num_threads()} torch threads, float64")
    print(f"numpy FK (markers + all named points): {mean_ms(lambda: forward_kinematics(model, q), args.repeats):7.2f} ms")
    print(f"numpy FK + segment frames P x 15 x 4 x 4: "
          f"{mean_ms(lambda: forward_kinematics(model, q).segment_frames(), args.repeats):7.2f} ms")
    print(f"torch FK (same steps):                 {mean_ms(lambda: torch_fk(model, qt), args.repeats):7.2f} ms")
    qt32 = qt.float()
    print(f"torch FK float32:                      {mean_ms(lambda: torch_fk(model, qt32), args.repeats):7.2f} ms")


if __name__ == "__main__":
    main()
