"""Renderer and observation pipeline: background subtraction against the renderer's exact masks."""
import numpy as np
import pytest

from data_tools.sequences.sequence import read_sequence
from data_tools.synthesis.raster import rasterize
from data_tools.synthesis.synth import SynthConfig, synthesize
from likelihoods.observations import ObservationConfig, edge_map, observe, silhouette
from tracker.app.visualize import model_masks


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def silhouette_ious(out) -> list[float]:
    seq = read_sequence(out.root)
    return [iou(silhouette(seq.image(k, v), seq.background(v)), out.masks[k][v])
            for k in range(seq.n_frames) for v in range(seq.n_views)]


def test_rasterizer_depth_order_and_coverage():
    # Two squares (two triangles each) over pixels 2..7; the nearer one (depth 100) is drawn second.
    sq = np.array([[2.0, 2.0], [7.0, 2.0], [7.0, 7.0], [2.0, 7.0]])
    pix = np.concatenate([sq, sq + [2.0, 0.0]])
    depth = np.array([200.0] * 4 + [100.0] * 4)
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    f = rasterize(pix, depth, faces, 12, 10)
    assert f.pixel.size == 6 * 8  # columns 2..9, rows 2..7
    ys, xs = np.divmod(f.pixel, 12)
    near = f.face >= 2
    assert np.all(near == (xs >= 4)) and np.allclose(f.depth[near], 100.0) and np.allclose(f.depth[~near], 200.0)
    assert np.allclose(f.bary.sum(axis=1), 1.0)
    # A scene closer than both hides everything.
    assert rasterize(pix, depth, faces, 12, 10, zbuffer=np.full((10, 12), 50.0)).pixel.size == 0


def test_person_is_rendered_in_every_view_with_jittered_widths(synthetic_walk):
    meta = read_sequence(synthetic_walk.root).meta
    factors = np.array(meta["render_width_factors"])
    assert factors.shape == (15,) and np.all(np.abs(factors - 1) <= 0.1) and np.std(factors) > 0.01
    for views in synthetic_walk.masks:
        for m in views:
            assert 1500 < m.sum() < 8000  # a person about 170 px tall


def test_background_subtraction_default_noise(synthetic_walk):
    ious = silhouette_ious(synthetic_walk)
    assert min(ious) > 0.8 and np.mean(ious) > 0.9


@pytest.mark.parametrize("config", [ObservationConfig(), ObservationConfig(compensate_gain=False),
                                    ObservationConfig(blur_sigma=1.0), ObservationConfig(diff_threshold=1.0)],
                         ids=["default", "no gain", "blurred", "noise decides"])
@pytest.mark.parametrize("grey", [False, True], ids=["rgb", "grey"])
def test_silhouette_is_the_thresholded_colour_distance(synthetic_walk, config, grey):
    """The compiled pass marks exactly the pixels whose colour distance to the (gain-compensated) plate exceeds
    max(threshold, 3 sigma), the distance and sigma computed here as plain float32 array operations over the
    whole image (before the morphological clean-up, which is switched off). The image is brightened by 15% (so
    that the gain is not 1 and distances are not whole numbers), given mirrored (not contiguous), and the plate
    is prepared once and used for two frames."""
    import cv2

    from likelihoods.observations import BackgroundPlate

    config = ObservationConfig(**{**config.__dict__, "open_radius": 0, "close_radius": 0, "min_area": 0})
    seq = read_sequence(synthetic_walk.root)
    background = seq.background(2)[:, ::-1]
    if grey:
        background = cv2.cvtColor(np.ascontiguousarray(background), cv2.COLOR_RGB2GRAY)
    plate = BackgroundPlate.of(background, config)

    def blurred(a):
        a = a.astype(np.float32)
        return cv2.GaussianBlur(a, (0, 0), config.blur_sigma) if config.blur_sigma else a
    for frame in (1, 2):
        image = np.clip(seq.image(frame, 2)[:, ::-1] * 1.15, 0, 255).astype(np.uint8)
        if grey:
            image = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
        img, bg = blurred(image), blurred(background)
        gain = 1.0
        if config.compensate_gain:
            grey_of = (lambda a: a) if grey else (lambda a: a.mean(axis=2))
            gi, gb = grey_of(img[::4, ::4]), grey_of(bg[::4, ::4])
            gain = float(np.median(gi[gb > 20] / gb[gb > 20]))
            assert abs(gain - 1.15) < 0.05
        diff = np.abs(img - bg * np.float32(gain))
        dist = diff if grey else np.sqrt(np.square(diff).sum(axis=2))
        sigma = float(np.median(dist[::4, ::4])) / (0.6745 if grey else 1.5382)
        threshold = max(config.diff_threshold, config.noise_factor * sigma)
        if config.diff_threshold == 1.0:
            assert threshold > 1.0  # the noise estimate, not the floor, sets it
        want = dist > threshold
        got = silhouette(image, plate, config)
        assert 0 < want.sum() < want.size and np.array_equal(got, want)


def test_squared_threshold_compares_squares_as_the_square_roots_compare():
    from likelihoods.observations import squared_threshold

    for t in np.random.default_rng(0).uniform(1.0, 60.0, 200).tolist() + [10.0, 3.0]:
        s, t32 = squared_threshold(t), np.float32(t)
        near = s + np.arange(-40, 40, dtype=np.float32) * np.spacing(s)
        assert np.array_equal(near > s, np.sqrt(near) > t32)


@pytest.mark.slow
def test_background_subtraction_clean_frames(walk_07_11, tmp_path):
    out = synthesize(walk_07_11, tmp_path / "clean", SynthConfig(start=80, frames=3, noise=0.0, seed=1),
                     keep_masks=True)
    assert min(silhouette_ious(out)) > 0.9


@pytest.mark.slow
def test_lighting_change_is_compensated(walk_07_11, tmp_path):
    out = synthesize(walk_07_11, tmp_path / "light", SynthConfig(start=80, frames=2, lighting_change=0.3, seed=2),
                     keep_masks=True)
    ious = silhouette_ious(out)
    assert min(ious) > 0.8
    seq = read_sequence(out.root)
    raw = silhouette(seq.image(1, 0), seq.background(0), ObservationConfig(compensate_gain=False))
    assert iou(raw, out.masks[1][0]) < 0.5  # without compensation the whole scene differs from the plate


@pytest.mark.slow
def test_occluder_hides_the_person_in_camera_0(walk_07_11, tmp_path):
    # In 07_11 the walk passes behind the pillar around frames 20-60 (fully hidden near frame 36).
    free = synthesize(walk_07_11, tmp_path / "a", SynthConfig(start=20, frames=3, seed=4), keep_masks=True)
    occl = synthesize(walk_07_11, tmp_path / "b", SynthConfig(start=20, frames=3, seed=4, occluder=True),
                      keep_masks=True)
    for k in range(3):
        assert free.masks[k][0].sum() - occl.masks[k][0].sum() > 500
        assert not np.any(occl.masks[k][0] & ~free.masks[k][0])
        assert np.array_equal(free.masks[k][1], occl.masks[k][1])  # other views unaffected


@pytest.mark.slow
def test_missing_camera_is_black(walk_07_11, tmp_path):
    out = synthesize(walk_07_11, tmp_path / "m", SynthConfig(start=0, frames=2, missing_camera=2))
    seq = read_sequence(out.root)
    assert not seq.image(1, 2).any() and seq.image(1, 1).any()


def test_turn_moves_the_walk_in_another_direction_with_the_same_body(walk_07_11):
    from data_tools.synthesis.synth import turned
    from tracker.core.errors import InputError
    from tracker.core.kinematics import markers

    quarter = turned(walk_07_11, 90.0)
    step, quarter_step = (np.diff(r.poses[:, :2], axis=0).mean(axis=0) for r in (walk_07_11, quarter))
    assert np.allclose(quarter_step, [-step[1], step[0]], atol=1e-9)  # +y becomes -x, counter-clockwise
    # The model's markers at the turned poses are the turned markers: root position and orientation agree.
    at_turned = markers(walk_07_11.model, quarter.poses)
    assert np.abs(at_turned - quarter.model_markers).max() < 1e-6
    assert np.abs(at_turned[..., 2] - walk_07_11.model_markers[..., 2]).max() < 1e-6  # heights unchanged
    assert np.allclose(quarter.poses[:, 6:], walk_07_11.poses[:, 6:])  # the joints are untouched
    assert np.abs(np.diff(quarter.poses[:, 3:6], axis=0)).max() < 0.5  # the orientation stays continuous
    assert turned(walk_07_11, 0.0) is walk_07_11
    for bad in (400.0, float("nan"), "left"):
        with pytest.raises(InputError, match="turn must be"):
            turned(walk_07_11, bad)


@pytest.mark.slow
def test_a_turned_sequence_renders_with_its_ground_truth_on_the_person(walk_07_11, tmp_path):
    out = synthesize(walk_07_11, tmp_path / "t", SynthConfig(start=40, frames=2, seed=3, turn=90.0),
                     keep_masks=True)
    seq = read_sequence(out.root)
    for v in range(seq.n_views):
        assert iou(model_masks(seq.model, seq.groundtruth.poses[1], seq.rig)[v], out.masks[1][v]) > 0.6


def test_projected_ground_truth_covers_rendered_person(synthetic_walk):
    seq = read_sequence(synthetic_walk.root)
    for k in range(seq.n_frames):
        masks = model_masks(seq.model, seq.groundtruth.poses[k], seq.rig)
        for v in range(seq.n_views):
            assert iou(masks[v], synthetic_walk.masks[k][v]) > 0.6


def test_edge_map_range_and_falloff(synthetic_walk):
    seq = read_sequence(synthetic_walk.root)
    obs = observe([seq.image(0, v) for v in range(4)], [seq.background(v) for v in range(4)])
    e = obs.edges
    assert e.dtype == np.float32 and e.min() >= 0.0 and e.max() == pytest.approx(1.0)
    # Edges sit on the silhouette boundary: the map is high there and falls to ~0 far from the person.
    sil = obs.silhouettes[0] > 0.5
    import cv2
    boundary = sil & ~cv2.erode(sil.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    far = ~cv2.dilate(sil.astype(np.uint8), np.ones((61, 61), np.uint8)).astype(bool)
    assert e[0][boundary].mean() > 0.6 and e[0][far].max() < 1e-3
    # Smooth fall-off: one pixel from an isolated line the value is exp(-1 / (2 sigma^2)).
    img = np.zeros((40, 40), np.uint8)
    img[:, 20:] = 200
    line = edge_map(img)
    assert line[20, 19] == pytest.approx(1.0) and 0.3 < line[20, 24] < 0.9 and line[20, 35] < 0.01


def test_bodytrack_initial_pose_inside_masks(bodytrack_dir):
    from tracker.core.cones import cone_points, volume_grid
    from tracker.core.kinematics import forward_kinematics

    seq = read_sequence(bodytrack_dir)
    assert seq.layout == "bodytrack" and seq.n_views == 4 and seq.n_frames == 1 and seq.model.n_dofs == 31
    frames = forward_kinematics(seq.model, seq.initial_poses[0]).segment_frames()
    pts = cone_points(seq.model, frames, *volume_grid(8, 8, (0.0, 0.5, 0.8)))
    pix, depth = seq.rig.project(pts.reshape(-1, 3))
    for v in range(4):
        mask = seq.mask(0, v)
        xy = np.rint(pix[v]).astype(int)
        ok = (xy[:, 0] >= 0) & (xy[:, 0] < 640) & (xy[:, 1] >= 0) & (xy[:, 1] < 480) & (depth[v] > 0)
        inside = np.zeros(len(xy), bool)
        inside[ok] = mask[xy[ok, 1], xy[ok, 0]]
        assert inside.mean() > 0.8, v
    obs = observe([seq.image(0, v) for v in range(4)], masks=[seq.mask(0, v) for v in range(4)])
    assert obs.silhouettes.shape == (4, 480, 640) and 0 < obs.edges.mean() < 0.5


def test_synth_settings_take_numpy_numbers_and_refuse_what_is_not_a_number():
    from tracker.core.errors import InputError

    config = SynthConfig(views=np.int64(2), seed=np.int64(3), turn=np.float32(45.0))
    assert type(config.views) is int and type(config.seed) is int and type(config.turn) is float
    for bad in ({"noise": 10 ** 400}, {"turn": float("inf")}, {"views": True}, {"frames": 0}, {"width": 2.5}):
        with pytest.raises(InputError, match="synth setting"):
            SynthConfig(**bad)


def test_observe_refuses_views_and_masks_of_other_sizes():
    image = np.zeros((40, 60, 3), np.uint8)
    mask = np.zeros((40, 60), bool)
    mask[10:30, 20:40] = True
    both = observe([image, image], masks=[mask, mask], threads=2)
    assert both.silhouettes.shape == (2, 40, 60) and both.silhouettes[1, 20, 30] == 1.0
    with pytest.raises(ValueError, match="view 1: image of 40 x 50 pixels"):
        observe([image, image[:, :50]], masks=[mask, mask[:, :50]])
    with pytest.raises(ValueError, match="view 1: mask of shape \\(1, 60\\)"):
        observe([image, image], masks=[mask, mask[:1]])
