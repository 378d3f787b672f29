"""The likelihood's CPU path, one compiled loop (:mod:`likelihoods.compiled_costs`), against its array-API path
(``EdgeSilhouetteLikelihood.array_costs``, the steps the GPU runs) computed with numpy in float64: the same costs
on random poses and on poses near the truth, on a synthetic frame, on PARSEC's real frame (lens distortion) and
with a skewed, distorted rig; the same corners for the bidirectional term; bad shapes refused."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from likelihoods.compiled_costs import ConeCostTables, cone_costs
from likelihoods.edge_silhouette import EdgeSilhouetteConfig, EdgeSilhouetteLikelihood
from tracker.core.cameras import CameraRig
from tracker.core.kinematics import forward_kinematics


def _poses(model, truth: np.ndarray, rng, n_near: int, n_random: int) -> np.ndarray:
    """Poses near ``truth`` (50 mm, 0.05 rad) and poses drawn anywhere within the limits (root within 1.5 m),
    all within the limits."""
    near = truth + rng.standard_normal((n_near, truth.size)) * np.r_[[50.0] * 3, [0.05] * (truth.size - 3)]
    lower, upper = np.maximum(model.lower, -3.0), np.minimum(model.upper, 3.0)
    anywhere = rng.uniform(lower, upper, (n_random, model.n_dofs))
    anywhere[:, :3] = truth[:3] + rng.normal(0.0, 1500.0, (n_random, 3))
    poses = np.clip(np.concatenate([near, anywhere]), model.lower, model.upper)
    assert model.within_limits(poses).all()
    return poses


def _assert_same_costs(likelihood: EdgeSilhouetteLikelihood, frame, poses: np.ndarray) -> None:
    scorer = likelihood.prepare(frame)
    compiled = scorer.terms(poses)
    edge, sil, cover = likelihood.array_costs(poses, scorer.maps, np.float64)
    # float64 in both; the array path's means sum float32 values in float32 (about 1e-7 of a cost)
    np.testing.assert_allclose(compiled.edge, edge, rtol=0, atol=1e-6)
    np.testing.assert_allclose(compiled.silhouette, sil, rtol=0, atol=1e-6)
    if cover is not None:
        np.testing.assert_array_equal(compiled.coverage, cover)
    sharpness = likelihood.config.sharpness
    want = -sharpness * (edge + sil + (0.0 if cover is None else cover)).sum(axis=1)
    np.testing.assert_allclose(compiled.log_likelihood, want, rtol=0, atol=1e-4)
    assert 0.0 < compiled.edge.min() and compiled.edge.max() <= 1.0 and compiled.silhouette.min() < 0.5


@pytest.mark.parametrize("bidirectional", [False, True])
def test_compiled_costs_equal_the_array_path_on_a_synthetic_frame(walk_32_frames, rng, bidirectional):
    seq = walk_32_frames
    k = 12
    poses = _poses(seq.model, seq.groundtruth.poses[k], rng, 300, 100)
    # across the right and the left edge of camera 0's image (6 m away, focal length 600 px: 3.2 m is 320 px)
    poses[:20, :3] += np.linspace(-3400.0, 3400.0, 20)[:, None] * seq.rig[0].R[0]
    poses[-1, :3] = seq.rig[0].centre - 3000.0 * seq.rig[0].R[2]  # behind camera 0: every cone reads cost 1
    likelihood = EdgeSilhouetteLikelihood(seq.model, seq.rig, EdgeSilhouetteConfig(bidirectional=bidirectional))
    _assert_same_costs(likelihood, seq.frame(k, range(4)), poses)
    behind = likelihood.prepare(seq.frame(k, range(4))).terms(poses[-1:])
    assert np.all(behind.edge[0, 0] == 1.0)
    if bidirectional:  # cones behind the camera cover no foreground (a degenerate outline once covered it all)
        assert behind.coverage[0, 0] == 1.0


def test_compiled_costs_equal_the_array_path_on_the_real_bodytrack_frame(bodytrack_dir, rng):
    import tracker

    seq = tracker.load_sequence(bodytrack_dir)
    assert seq.rig.has_distortion
    poses = _poses(seq.model, np.asarray(seq.initial_poses)[-1], rng, 400, 100)
    _assert_same_costs(EdgeSilhouetteLikelihood(seq.model, seq.rig), seq.frame(0, range(seq.n_views)), poses)


def test_compiled_costs_equal_the_array_path_with_skew_and_every_distortion_term(walk_32_frames, rng):
    seq = walk_32_frames
    cameras = [dataclasses.replace(c, skew=0.01 * (i + 1), dist=(-0.2, 0.05, 0.003, -0.002, 0.01))
               for i, c in enumerate(seq.rig.cameras)]
    likelihood = EdgeSilhouetteLikelihood(seq.model, CameraRig(cameras))
    _assert_same_costs(likelihood, seq.frame(5, range(4)), _poses(seq.model, seq.groundtruth.poses[5], rng, 300, 50))


def test_cone_costs_refuses_inconsistent_shapes_and_dtypes(walk_32_frames, rng):
    seq = walk_32_frames
    likelihood = EdgeSilhouetteLikelihood(seq.model, seq.rig)
    maps = likelihood.prepare(seq.frame(3, range(4))).maps
    kinematics = forward_kinematics(seq.model, seq.groundtruth.poses[3:8])
    tables = ConeCostTables.of(seq.model, seq.rig, likelihood.weights)
    P, V = 5, 4
    good = dict(kinematics=kinematics, tables=tables, edge_map=maps.edge, silhouette_map=maps.silhouette,
                view_offset=maps.view_offset, height=maps.height, width=maps.width,
                n_contour=likelihood.n_contour, edge_out=np.empty((P, V)), silhouette_out=np.empty((P, V)))
    cone_costs(**good)
    assert np.all((0 < good["edge_out"]) & (good["edge_out"] <= 1))
    bad = {"outputs the wrong way round": dict(edge_out=np.empty((V, P))),
           "float32 outputs": dict(edge_out=np.empty((P, V), np.float32)),
           "too few offsets": dict(view_offset=maps.view_offset[:2]),
           "an offset past the maps": dict(view_offset=maps.view_offset + maps.height * maps.width),
           "no contour points": dict(n_contour=0),
           "maps of another size": dict(height=maps.height + 1),
           "float64 maps": dict(edge_map=maps.edge.astype(float)),
           "frames of another model": dict(kinematics=dataclasses.replace(
               kinematics, rotations=kinematics.rotations[:, :3], origins=kinematics.origins[:, :3])),
           "corners of the wrong shape": dict(corners_out=(np.empty((V, P, 2, 4)), np.empty((V, P, 2, 4)))),
           "ellipses without corners": dict(ellipses_out=(np.empty((V, P, 15, 6)), np.empty((V, P, 15, 6)))),
           "ellipses of the wrong shape": dict(corners_out=(np.empty((V, P, 15, 4)), np.empty((V, P, 15, 4))),
                                               ellipses_out=(np.empty((V, P, 15, 4)), np.empty((V, P, 15, 4))))}
    for name, change in bad.items():
        with pytest.raises(ValueError, match="cone costs"):
            cone_costs(**{**good, **change})
    for change in (dict(intrinsics=tables.intrinsics[:2]), dict(cone=tables.cone[:, :3]),
                   dict(seg_link=tables.seg_link.astype(np.int32)), dict(weights=tables.weights[:3]),
                   dict(weights=tables.weights.astype(np.float32)), dict(camera_t=tables.camera_t[:, :2])):
        with pytest.raises(ValueError, match="cone cost tables"):
            dataclasses.replace(tables, **change)
