"""Sequence formats (own layout round trip, bodytrack reader), the 10-cone model, and bad inputs."""
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest

from data_tools.sequences.bodytrack import read_body_shape, read_pose_parameters, read_poses
from data_tools.sequences.sequence import read_image, read_sequence, write_image
from tracker.app.cli import main
from tracker.core.errors import InputError
from tracker.core.kinematics import forward_kinematics, point_jacobians
from tracker.core.parsec_body import ten_cone_model


def test_own_format_round_trip(synthetic_walk, walk_07_11):
    seq = read_sequence(synthetic_walk.root)
    assert seq.layout == "own" and seq.n_frames == 6 and seq.n_views == 4 and seq.fps == 60
    gt = seq.groundtruth
    shift = np.array(seq.meta["ground_plane_shift_mm"])
    assert np.allclose(gt.poses[:, :2] + shift, walk_07_11.poses[40:46, :2])
    assert np.allclose(gt.poses[:, 2:], walk_07_11.poses[40:46, 2:])
    assert np.allclose(gt.markers[..., :2] + shift, walk_07_11.markers[40:46, :, :2])
    # The model rebuilt from meta.json is the subject's model.
    assert np.allclose(forward_kinematics(seq.model, gt.poses).markers[..., 2],
                       forward_kinematics(walk_07_11.model, walk_07_11.poses[40:46]).markers[..., 2])
    assert seq.rig.names == ["cam0", "cam1", "cam2", "cam3"]
    img = seq.image(3, 2)
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8


def test_image_round_trip(tmp_path, rng):
    colour = rng.integers(0, 256, (5, 7, 3), dtype=np.uint8)
    grey = rng.integers(0, 256, (5, 7), dtype=np.uint8)
    write_image(tmp_path / "c.png", colour)
    write_image(tmp_path / "g.png", grey)
    assert np.array_equal(read_image(tmp_path / "c.png", 7, 5), colour)
    assert np.array_equal(read_image(tmp_path / "g.png", 7, 5), grey)


def test_every_8_bit_png_colour_type_reads_as_grey_or_rgb(tmp_path, rng):
    """Grey with alpha stays grey, RGB with alpha loses its alpha, a palette image is expanded to RGB."""
    grey = rng.integers(0, 256, (5, 7), dtype=np.uint8)
    colour = rng.integers(0, 256, (5, 7, 3), dtype=np.uint8)
    alpha = rng.integers(0, 256, (5, 7), dtype=np.uint8)
    palette = np.array([[0, 0, 0], [255, 0, 0], [0, 128, 255]], np.uint8)
    index = rng.integers(0, 3, (5, 7), dtype=np.uint8)
    files = {"ga.png": (np.dstack([grey, alpha]), 4, b""), "rgba.png": (np.dstack([colour, alpha]), 6, b""),
             "p.png": (index, 3, palette.tobytes())}
    for name, (pixels, colour_type, plte) in files.items():
        (tmp_path / name).write_bytes(_png(pixels, colour_type, plte))
    assert np.array_equal(read_image(tmp_path / "ga.png", 7, 5), grey)
    assert np.array_equal(read_image(tmp_path / "ga.png", 7, 5, rgb=True), np.repeat(grey[..., None], 3, axis=2))
    assert np.array_equal(read_image(tmp_path / "rgba.png", 7, 5), colour)
    assert np.array_equal(read_image(tmp_path / "p.png", 7, 5), palette[index])


def _png(pixels: np.ndarray, colour_type: int, plte: bytes = b"") -> bytes:
    """An 8-bit PNG of ``pixels`` (``H x W`` or ``H x W x C``, in the channel order of ``colour_type``), written
    here because OpenCV writes neither grey with alpha nor palettes."""
    import struct
    import zlib

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    h, w = pixels.shape[:2]
    rows = b"".join(b"\x00" + row.tobytes() for row in pixels)  # filter type 0 on every row
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, colour_type, 0, 0, 0))
            + (chunk(b"PLTE", plte) if plte else b"") + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def test_bodytrack_files(bodytrack_dir):
    limbs, lengths = read_body_shape(bodytrack_dir / "BodyShapeParameters.txt")
    assert limbs.shape == (10, 4) and lengths.shape == (18,)
    pose = read_poses(bodytrack_dir / "InitialPose.txt")
    assert pose.shape == (1, 31)
    params = read_pose_parameters(bodytrack_dir / "PoseParameters.txt")
    assert params.std.shape == (31,) and np.all(params.lower <= params.upper)
    seq = read_sequence(bodytrack_dir)
    assert np.allclose(seq.diffusion_std, params.std)
    # Standing person: head above thorax above pelvis, ankles near the floor, stature plausible.
    m = forward_kinematics(seq.model, pose[0]).markers
    assert m[2, 2] > m[1, 2] > m[0, 2] and np.all(m[[11, 14], 2] < 100) and 1500 < m[2, 2] < 1900


def test_ten_cone_model_jacobians(bodytrack_dir, rng):
    seq = read_sequence(bodytrack_dir)
    model = seq.model
    q = seq.initial_poses[0] + rng.normal(0, 0.05, 31) * (np.arange(31) >= 6)
    J = point_jacobians(model, q)
    eps = 1e-6
    for d in range(31):
        dq = np.zeros(31)
        dq[d] = eps
        fd = (forward_kinematics(model, q + dq).points - forward_kinematics(model, q - dq).points) / (2 * eps)
        assert np.allclose(J[..., d], fd, atol=1e-4), model.dof_names[d]


def test_ten_cone_model_refuses_bad_shape():
    limbs = np.ones((10, 4))
    with pytest.raises(InputError, match="10x4"):
        ten_cone_model(np.ones((9, 4)), np.ones(18))
    limbs[3, 0] = 0
    with pytest.raises(InputError, match="right_upper_leg"):
        ten_cone_model(limbs, np.ones(18))


def run_cli(*args):
    r = subprocess.run([sys.executable, "-m", "tracker", *args], capture_output=True, text=True)
    err = r.stderr.strip().splitlines()
    return r.returncode, (err[-1] if err else "")


def copy_sequence(src, dst):
    shutil.copytree(src, dst)
    return dst


@pytest.mark.slow
def test_show_and_synth_cli(mocap_dir, tmp_path):
    out = tmp_path / "s"
    assert main(["synth", "--mocap", str(mocap_dir / "07" / "07_10.amc"), "--out", str(out), "--frames", "2",
                 "--cameras", "2", "--width", "320", "--height", "240", "--start", "10"]) == 0
    seq = read_sequence(out)
    assert seq.n_views == 2 and seq.n_frames == 2 and seq.image(0, 0).shape == (240, 320, 3)
    png = tmp_path / "grid.png"
    assert main(["show", str(out), "--frame", "1", "--out", str(png), "--video", str(tmp_path / "v.mp4")]) == 0
    assert cv2.imread(str(png)).shape == (240 + 32, 640, 3) and (tmp_path / "v.mp4").stat().st_size > 1000
    np.savez(tmp_path / "est.npz", poses=seq.groundtruth.poses)
    assert main(["show", str(out), "--poses", str(tmp_path / "est.npz"), "--out", str(png), "--overwrite"]) == 0


def test_show_bodytrack(bodytrack_dir, tmp_path):
    png = tmp_path / "bt.png"
    assert main(["show", str(bodytrack_dir), "--out", str(png)]) == 0
    assert cv2.imread(str(png)).shape == (960 + 32, 1280, 3)  # the views and the legend strip


@pytest.mark.slow
def test_bad_sequences_exit_2(synthetic_walk, bodytrack_dir, tmp_path):
    root = synthetic_walk.root
    cases = {}
    a = copy_sequence(root, tmp_path / "no_camera")
    shutil.rmtree(a / "images" / "cam1")
    cases["camera folder for 'cam1' is missing"] = a
    b = copy_sequence(root, tmp_path / "no_frame")
    (b / "images" / "cam2" / "000003.png").unlink()
    cases["frame 3 is missing"] = b
    c = copy_sequence(root, tmp_path / "small")
    write_image(c / "images" / "cam0" / "000000.png", np.zeros((240, 320, 3), np.uint8))
    cases["320x240 pixels but its camera is 640x480"] = c
    d = copy_sequence(root, tmp_path / "corrupt")
    (d / "images" / "cam3" / "000000.png").write_bytes(b"not a png at all")
    cases["cannot read image"] = d
    e = copy_sequence(bodytrack_dir, tmp_path / "bt_empty_mask")
    (e / "FG2" / "image0000.bmp").chmod(0o644)
    cv2.imwrite(str(e / "FG2" / "image0000.bmp"), np.zeros((480, 640), np.uint8))
    cases["foreground mask is all zero"] = e
    cases["sequence folder does not exist"] = tmp_path / "nowhere"
    for expected, folder in cases.items():
        code, err = run_cli("show", str(folder), "--out", str(tmp_path / "x.png"))
        assert code == 2 and expected in err and "Traceback" not in err, (expected, err)
    code, err = run_cli("show", str(root), "--frame", "6", "--out", str(tmp_path / "x.png"))
    assert code == 2 and "frame 6 out of range" in err


@pytest.mark.slow
def test_synth_frames_past_end_exit_2(mocap_dir, tmp_path):
    amc = str(mocap_dir / "07" / "07_11.amc")
    for args, expected in [(["--start", "150", "--frames", "20"], "runs past the end of the clip (158 frames"),
                           (["--start", "400"], "past the end of the clip"),
                           (["--frames", "0"], "must be at least 1"),
                           (["--missing-camera", "7", "--frames", "2"], "missing camera 7")]:
        code, err = run_cli("synth", "--mocap", amc, "--out", str(tmp_path / "o"), *args)
        assert code == 2 and expected in err and "Traceback" not in err, (args, err)



def test_tracking_views_of_different_image_sizes_is_refused_in_one_line(tmp_path):
    from data_tools.sequences.calibration import write_cameras_json
    from tracker.core.cameras import look_at

    seq = tmp_path / "seq"
    widths = {"a": 64, "b": 60}
    for cam, width in widths.items():
        (seq / "images" / cam).mkdir(parents=True)
        write_image(seq / "images" / cam / "000000.png", np.zeros((48, width, 3), np.uint8))
    write_cameras_json([look_at(cam, (3000.0, 1000.0 * k, 1500.0), (0.0, 0.0, 900.0), width, 48)
                        for k, (cam, width) in enumerate(widths.items())], seq / "cameras.json")
    from tracker.app.api import available_likelihoods, build_likelihood

    sequence = read_sequence(seq)  # a rig of portrait and landscape views is read, shown and exported alike
    with pytest.raises(InputError, match=r"image sizes differ \(a 64x48, b 60x48\)"):
        build_likelihood(available_likelihoods()[0], sequence)
    build_likelihood(available_likelihoods()[0], sequence, views=[1])  # one size among the views chosen
