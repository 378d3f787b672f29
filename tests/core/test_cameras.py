import json

import cv2
import numpy as np
import pytest

from data_tools.sequences.calibration import read_bodytrack_calibration, read_cameras_json, write_cameras_json
from tracker.core.cameras import CameraRig, default_rig, look_at, make_camera, monocular_rig
from tracker.core.errors import InputError
from tracker.core.rotations import exp_map_to_matrix


def random_camera(rng, name="c"):
    R = exp_map_to_matrix(rng.normal(size=3) * 0.3)
    t = np.array([0, 0, 4000.0]) + rng.normal(size=3) * 200
    dist = [rng.normal() * 0.2, rng.normal() * 0.05, rng.normal() * 1e-3, rng.normal() * 1e-3, rng.normal() * 0.01]
    return make_camera(name, 640, 480, 600 + rng.normal() * 20, 600 + rng.normal() * 20, 320 + rng.normal() * 5,
                       240 + rng.normal() * 5, R, t, 0.0, dist)


def test_projection_matches_opencv(rng):
    for _ in range(5):
        cam = random_camera(rng)
        X = rng.uniform(-800, 800, size=(500, 3))
        K = np.array([[cam.fx, 0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1]])
        ref, _ = cv2.projectPoints(X, cv2.Rodrigues(cam.R)[0], cam.t, K, np.array(cam.dist))
        pix, depth = cam.project(X)
        assert np.abs(pix - ref[:, 0, :]).max() < 1e-6
        assert np.allclose(depth, cam.points_in_camera(X)[:, 2])


def test_skew_by_hand():
    cam = make_camera("s", 100, 100, 500, 400, 50, 40, np.eye(3), [0, 0, 0], skew=0.1)
    pix, _ = cam.project(np.array([200.0, 100.0, 1000.0]))
    assert np.allclose(pix, [500 * (0.2 + 0.1 * 0.1) + 50, 400 * 0.1 + 40])


def test_rig_projects_batches_over_views(rng):
    rig = CameraRig([random_camera(rng, f"c{i}") for i in range(3)])
    X = rng.uniform(-500, 500, size=(7, 11, 3))  # P x K x 3
    pix, depth = rig.project(X)
    assert pix.shape == (7, 3, 11, 2) and depth.shape == (7, 3, 11)
    for v, cam in enumerate(rig.cameras):
        assert np.allclose(pix[:, v], cam.project(X)[0])


def test_default_rig_sees_capture_area():
    rig = default_rig()
    assert len(rig) == 4 and len(monocular_rig()) == 1
    g = np.linspace(-1500, 1500, 13)
    X, Y = np.meshgrid(g, g)
    pts = np.concatenate([np.stack([X.ravel(), Y.ravel(), np.full(X.size, h)], -1) for h in (0.0, 1900.0)])
    pix, depth = rig.project(pts)
    assert np.all(depth > 0)
    assert np.all((pix[..., 0] >= 0) & (pix[..., 0] <= 639) & (pix[..., 1] >= 0) & (pix[..., 1] <= 479))
    for cam in rig.cameras:
        assert cam.centre[2] == pytest.approx(2000.0)
        c, _ = cam.project(np.array([0, 0, 1000.0]))
        assert np.allclose(c, [319.5, 239.5])


def test_cameras_json_round_trip(tmp_path, rng):
    rig = CameraRig([random_camera(rng, "a"), random_camera(rng, "b")])
    path = tmp_path / "cameras.json"
    write_cameras_json(rig, path)
    back = read_cameras_json(path)
    X = rng.uniform(-500, 500, size=(20, 3))
    assert np.allclose(back.project(X)[0], rig.project(X)[0], atol=1e-9)
    assert back.names == ["a", "b"]


def test_cameras_json_rejects_non_rotation(tmp_path):
    cam = look_at("cam0", (3000, 0, 2000), (0, 0, 1000)).to_dict()
    cam["R"][0][0] += 0.5
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps({"cameras": [cam]}))
    with pytest.raises(InputError) as err:
        read_cameras_json(path)
    assert "cameras.json" in str(err.value) and "not a rotation" in str(err.value)


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.pop("fx"), "lacks fx"),
    (lambda d: d.update(fx=-1), "focal lengths must be positive"),
    (lambda d: d.update(t=[0, 0]), "t must be 3"),
    (lambda d: d.update(dist=[0] * 8), "at most 5"),
])
def test_cameras_json_bad_fields(tmp_path, mutate, message):
    cam = look_at("cam0", (3000, 0, 2000), (0, 0, 1000)).to_dict()
    mutate(cam)
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps({"cameras": [cam]}))
    with pytest.raises(InputError, match=message):
        read_cameras_json(path)
    path.write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        read_cameras_json(path)


def test_bodytrack_calibration(bodytrack_dir):
    cams = [read_bodytrack_calibration(bodytrack_dir / "CALIB" / f"Camera{k}.cal") for k in range(1, 5)]
    for cam in cams:
        assert 2000 < cam.centre[2] < 3000  # mounted about 2.5 m up
        assert cam.dist[0] < 0  # barrel distortion
    # The cameras look at a common region: the point nearest all optical axes projects inside every image.
    A, b = np.zeros((3, 3)), np.zeros(3)
    for cam in cams:
        d = cam.R[2]
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ cam.centre
    focus = np.linalg.solve(A, b)
    for cam in cams:
        pix, depth = cam.project(focus)
        assert depth > 0 and 0 <= pix[0] < 640 and 0 <= pix[1] < 480


def test_bodytrack_calibration_bad_file(tmp_path):
    path = tmp_path / "Camera1.cal"
    path.write_text("1 2 3\n")
    with pytest.raises(InputError, match="expected 25 numbers"):
        read_bodytrack_calibration(path)
