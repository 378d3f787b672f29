"""The likelihood contract (:class:`tracker.testing.LikelihoodContract`) run for the edge-silhouette
likelihood: its compiled CPU path against its array path (the steps a GPU runs) computed with numpy in float64,
with and without the bidirectional term, and its torch path (on the CPU) against the compiled one."""
from __future__ import annotations

import numpy as np
import pytest

from likelihoods.edge_silhouette import EdgeSilhouetteConfig, EdgeSilhouetteLikelihood
from tracker.testing import LikelihoodContract

FRAME = 12


class TestEdgeSilhouette(LikelihoodContract):
    """The compiled CPU path (the registered builder's on ``--device cpu``) on frame 12 of the synthetic walk, with
    the default bidirectional term."""

    config = EdgeSilhouetteConfig()
    device: str | None = None

    @pytest.fixture(autouse=True)
    def sequence(self, walk_32_frames):
        self.seq = walk_32_frames

    def make_likelihood(self):
        return EdgeSilhouetteLikelihood(self.seq.model, self.seq.rig, self.config, device=self.device)

    def make_frame(self):
        return self.seq.frame(FRAME, range(self.seq.n_views))

    def make_poses(self, rng, n):
        """Half near the true pose (50 mm, 0.05 rad), half anywhere within the limits (root within 1.5 m)."""
        model, truth = self.seq.model, self.seq.groundtruth.poses[FRAME]
        near = truth + rng.standard_normal((n - n // 2, truth.size)) * np.r_[[50.0] * 3, [0.05] * (truth.size - 3)]
        anywhere = rng.uniform(np.maximum(model.lower, -3.0), np.minimum(model.upper, 3.0), (n // 2, truth.size))
        anywhere[:, :3] = truth[:3] + rng.normal(0.0, 1500.0, (n // 2, 3))
        return np.clip(np.concatenate([near, anywhere]), model.lower, model.upper)

    def array_path(self, likelihood, prepared, poses):
        edge, sil, cover = likelihood.array_costs(poses, prepared.maps, np.float64)
        total = edge + sil + (0.0 if cover is None else cover)
        return -likelihood.config.sharpness * total.sum(axis=1)


class TestEdgeSilhouetteOneDirectional(TestEdgeSilhouette):
    """The same without the bidirectional term (``bidirectional=False``)."""

    config = EdgeSilhouetteConfig(bidirectional=False)


class TestEdgeSilhouetteTorch(TestEdgeSilhouette):
    """The torch path (``device="cpu"``; on a GPU the same steps run on ``cuda``), in float32 from the camera
    frames on, against the compiled float64 path (measured: 3.5e-6 apart at most)."""

    device = "cpu"

    def array_path(self, likelihood, prepared, poses):
        compiled = EdgeSilhouetteLikelihood(self.seq.model, self.seq.rig, self.config)
        return compiled.prepare(self.make_frame())(poses)
