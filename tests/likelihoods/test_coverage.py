"""The bidirectional term (the foreground no projected cone covers): a cone's whole outline counts, its ends
included, and the term has no pull towards a nearer or a farther body, so that one camera sees depth."""
from __future__ import annotations

import numpy as np

from likelihoods.edge_silhouette import EdgeSilhouetteConfig, EdgeSilhouetteLikelihood, _uncovered, foreground_sample
from tracker.core.cameras import CameraRig, look_at
from tracker.core.cones import contour_corners, end_ellipse_points


def _outline_pixels(model, rig: CameraRig, pose: np.ndarray):
    """Contour corners and end-ellipse points of ``pose`` in ``rig``'s pixels (``V x 1 x S x 4`` and ``x 6``)."""
    likelihood = EdgeSilhouetteLikelihood(model, rig, EdgeSilhouetteConfig(bidirectional=True))
    rotations, origins = likelihood._segment_frames(pose[None])
    axes, origins = rig.frames_in_cameras(rotations, origins, np.float64)
    u, v = rig.pixels(*contour_corners(model, axes, origins))
    eu, ev = rig.pixels(*end_ellipse_points(model, axes, origins))
    return u, v, eu, ev


def test_a_cone_seen_down_its_axis_covers_its_end(walk_32_frames):
    """Looking down the torso's axis, no ruling is a contour and the quadrilateral is a sliver across the end;
    the end ellipse is the cone's picture, and every pixel inside it is covered."""
    seq = walk_32_frames
    model = seq.model
    pose = model.rest_pose()
    rotations, origins = EdgeSilhouetteLikelihood(model, seq.rig)._segment_frames(pose[None])
    torso = [s.name for s in model.segments].index("torso")
    top = origins[0, torso] + rotations[0, torso][:, 2] * model.segments[torso].length  # its distal end
    # A camera 2 m above the torso's top, looking down its axis.
    axis = rotations[0, torso][:, 2]
    above = CameraRig([look_at("above", top + 2000.0 * axis, top, up=rotations[0, torso][:, 0])])
    u, v, eu, ev = _outline_pixels(model, above, pose)
    centre = np.array([eu[0, 0, torso, 3], ev[0, 0, torso, 3]])
    a = np.array([eu[0, 0, torso, 4], ev[0, 0, torso, 4]]) - centre
    b = np.array([eu[0, 0, torso, 5], ev[0, 0, torso, 5]]) - centre
    angles = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
    disc = centre + 0.8 * (np.cos(angles)[:, None] * a + np.sin(angles)[:, None] * b)  # inside the top end
    only_torso = (slice(None), slice(None), slice(torso, torso + 1))
    quad_only = _uncovered(u[only_torso], v[only_torso], np.full_like(eu[only_torso], -1e6),
                           np.full_like(ev[only_torso], -1e6), [disc])
    with_ends = _uncovered(u[only_torso], v[only_torso], eu[only_torso], ev[only_torso], [disc])
    assert quad_only[0, 0] >= 0.75 and with_ends[0, 0] == 0.0


def test_the_truth_leaves_no_foreground_uncovered(walk_32_frames):
    """At the true pose the cones' outlines cover the sampled foreground (the quadrilaterals alone left 11-16%
    of it, the ends of every cone, so that a larger, nearer body scored better)."""
    seq = walk_32_frames
    for frame in (5, 20):
        scorer = EdgeSilhouetteLikelihood(seq.model, seq.rig, EdgeSilhouetteConfig(bidirectional=True)).prepare(
            seq.frame(frame, range(4)))
        coverage = scorer.terms(seq.groundtruth.poses[frame][None]).coverage[0]
        assert np.all(coverage < 0.05), coverage


def test_one_camera_prefers_the_true_depth(walk_32_frames):
    """Moving the true pose along camera 0's ray in steps of 50 mm: with one camera the bidirectional likelihood
    is highest at the truth (with the quadrilaterals alone, 50 mm nearer scored 0.6-1.0 better), and a body
    300 mm farther (smaller, so inside the silhouette) scores worse than one 100 mm farther; the one-directional
    likelihood lets it off far more lightly."""
    seq = walk_32_frames
    rig = CameraRig([seq.rig[0]])
    steps = np.arange(-300.0, 301.0, 50.0)
    for frame in (5, 15, 25):
        truth = seq.groundtruth.poses[frame]
        ray = truth[:3] - seq.rig[0].centre
        poses = np.repeat(truth[None], len(steps), axis=0)
        poses[:, :3] += steps[:, None] * ray / np.linalg.norm(ray)
        both = EdgeSilhouetteLikelihood(seq.model, rig, EdgeSilhouetteConfig(bidirectional=True))
        one = EdgeSilhouetteLikelihood(seq.model, rig, EdgeSilhouetteConfig(bidirectional=False))
        ll = both.prepare(seq.frame(frame, [0]))(poses)
        ll_one = one.prepare(seq.frame(frame, [0]))(poses)
        at = {d: i for i, d in enumerate(steps)}
        assert steps[np.argmax(ll)] == 0.0, (frame, ll)
        assert ll[at[300.0]] < ll[at[100.0]] < ll[at[0.0]]
        far_cost, far_cost_one = ll[at[0.0]] - ll[at[300.0]], ll_one[at[0.0]] - ll_one[at[300.0]]
        assert far_cost > far_cost_one + 1.0, (frame, far_cost, far_cost_one)


def test_the_foreground_sample_keeps_off_the_outline():
    """The sampled pixels lie at least two pixels inside the silhouette's outline, where it has an inside."""
    silhouette = np.zeros((60, 80), np.float32)
    silhouette[10:50, 20:60] = 1.0
    points = foreground_sample(silhouette, 500)
    assert len(points) == 500
    assert points[:, 0].min() >= 22 and points[:, 0].max() <= 57
    assert points[:, 1].min() >= 12 and points[:, 1].max() <= 47
    thin = np.zeros((60, 80), np.float32)
    thin[20:23, 10:70] = 1.0  # thinner than the margin: sampled whole rather than not at all
    assert len(foreground_sample(thin, 500)) == 180
