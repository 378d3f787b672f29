"""Calibration readers of other tools' formats: the example's two files describe one rig, and a synthetic rig
written as each format reads back to the same pixels; bad files are one line naming the file."""
from __future__ import annotations

import numpy as np
import pytest

from data_tools.sequences.rig_formats import FORMATS, calibration_format, read_rig, write_rig
from tests.conftest import SHARED, need_shared
from tracker.core.cameras import CameraRig, look_at, make_camera
from tracker.core.errors import InputError

EXAMPLE = SHARED / "realvideo" / "pose2sim_static"
#: Points on and around the example's person (world mm, z up): head, feet, a hand.
PERSON = np.array([[-1100.0, -100.0, 1650.0], [-1100.0, 70.0, 20.0], [-900.0, -500.0, 1000.0]])


def synthetic_rig() -> CameraRig:
    """Two cameras with distortion, skew-free, one portrait one landscape, not centred principal points."""
    a = look_at("left", (4000.0, -3000.0, 1800.0), (0.0, 0.0, 900.0), 1080, 1920, 1500.0)
    b = look_at("right", (-3500.0, 2500.0, 2200.0), (100.0, 0.0, 1000.0), 640, 480, 600.0)
    a = make_camera(a.name, a.width, a.height, a.fx, a.fy * 1.001, 530.2, 961.7, a.R, a.t,
                    dist=(-0.05, 0.12, 0.001, -0.0005, 0.01))
    b = make_camera(b.name, b.width, b.height, b.fx, b.fy, 322.5, 238.1, b.R, b.t, dist=(0.02, -0.01, 0, 0, 0))
    return CameraRig([a, b])


@pytest.mark.parametrize("name", ["rig.toml", "rig.qca.txt", "rig.yml", "rig.xml", "rig.json"])
def test_synthetic_rig_round_trips_through_every_format(tmp_path, name):
    rig = synthetic_rig()
    write_rig(rig, tmp_path / name)
    back = read_rig(tmp_path / name)
    assert back.names == rig.names
    assert [(c.width, c.height) for c in back.cameras] == [(c.width, c.height) for c in rig.cameras]
    points = np.random.default_rng(0).uniform([-800, -800, 0], [800, 800, 1900], (50, 3))
    assert np.abs(back.project(points)[0] - rig.project(points)[0]).max() < 1e-3  # px
    assert np.allclose([c.centre for c in back.cameras], [c.centre for c in rig.cameras], atol=1e-6)  # mm


def test_formats_are_recognised_by_name(tmp_path):
    write_rig(synthetic_rig(), tmp_path / "c.xml")
    assert calibration_format(tmp_path / "c.xml") == "opencv"
    write_rig(synthetic_rig(), tmp_path / "q.qca.txt")
    assert [calibration_format(tmp_path / n) for n in ("a.toml", "q.qca.txt", "a.yaml", "cameras.json")] == \
        ["toml", "qca", "opencv", "json"]
    assert set(FORMATS) == {"toml", "qca", "opencv", "json"}


@pytest.mark.shared
def test_example_toml_and_qualisys_describe_the_same_rig():
    toml = read_rig(need_shared(EXAMPLE / "Calib_qualisys.toml"))
    qca = read_rig(EXAMPLE / "Calib.qca.txt")
    assert toml.names == qca.names == ["cam_01", "cam_02", "cam_03", "cam_04"]
    for a, b in zip(toml.cameras, qca.cameras):
        assert (a.width, a.height) == (b.width, b.height) == (1088, 1920)  # portrait
        assert np.allclose(a.R, b.R, atol=1e-9) and np.allclose(a.t, b.t, atol=1e-6)  # mm
        assert np.allclose([a.fx, a.fy, a.cx, a.cy], [b.fx, b.fy, b.cx, b.cy], atol=1e-4)  # px
    # The TOML's distortion coefficients are the Qualisys ones divided by 64 (its converter's choice), which
    # moves points on the person by at most a few pixels.
    gap = np.linalg.norm(toml.project(PERSON)[0] - qca.project(PERSON)[0], axis=-1)
    assert gap.max() < 3.0
    # Both put the person in front of every camera, inside its image.
    pix, depth = qca.project(PERSON)
    assert np.all(depth > 2000) and np.all(pix[..., 0] > 0) and np.all(pix[..., 0] < 1088)
    assert np.all(pix[..., 1] > 0) and np.all(pix[..., 1] < 1920)


def test_opencv_file_without_sizes_takes_them_from_the_caller(tmp_path):
    import cv2

    rig = synthetic_rig()
    write_rig(rig, tmp_path / "full.yml")
    fs = cv2.FileStorage(str(tmp_path / "full.yml"), cv2.FILE_STORAGE_READ)
    out = cv2.FileStorage(str(tmp_path / "intri.yml"), cv2.FILE_STORAGE_WRITE)
    ext = cv2.FileStorage(str(tmp_path / "extri.yml"), cv2.FILE_STORAGE_WRITE)
    out.startWriteStruct("names", cv2.FileNode_SEQ)
    for n in rig.names:
        out.write("", n)
    out.endWriteStruct()
    for n in rig.names:
        out.write(f"K_{n}", fs.getNode(f"K_{n}").mat())
        out.write(f"dist_{n}", fs.getNode(f"dist_{n}").mat())
        ext.write(f"R_{n}", cv2.Rodrigues(fs.getNode(f"Rot_{n}").mat())[0])
        ext.write(f"T_{n}", fs.getNode(f"T_{n}").mat())
    for f in (fs, out, ext):
        f.release()
    with pytest.raises(InputError, match="no image size"):
        read_rig([tmp_path / "intri.yml", tmp_path / "extri.yml"])
    back = read_rig([tmp_path / "intri.yml", tmp_path / "extri.yml"], sizes={"left": (1080, 1920),
                                                                            "right": (640, 480)})
    assert np.abs(back.project(PERSON)[0] - rig.project(PERSON)[0]).max() < 1e-6


@pytest.mark.parametrize("name, text, problem", [
    ("bad.toml", "[cam]\nmatrix = [[1, 0, 0], [0, 1, 0]]\n", "lacks distortions"),
    ("bad.toml", "[cam\n", "not valid TOML"),
    ("fish.toml", "[c]\nsize=[10,10]\nmatrix=[[5,0,5],[0,5,5],[0,0,1]]\ndistortions=[0,0,0,0]\nrotation=[0,0,0]\n"
                  "translation=[0,0,3]\nfisheye=true\n", "fisheye"),
    ("bad.toml", "[c]\nsize=[10,10]\nmatrix=[[5,0,5],[0,5,5]]\ndistortions=[0,0,0,0]\nrotation=[0,0,0]\n"
                 "translation=[0,0,3]\n", "must be 3x3"),
    ("bad.toml", "[c]\nsize=[10,10]\nmatrix=[[-5,0,5],[0,5,5],[0,0,1]]\ndistortions=[0,0,0,0]\n"
                 "rotation=[0,0,0]\ntranslation=[0,0,3]\n", "fx"),
    ("bad.qca.txt", "<calibration><cameras><camera serial='a'><transform r11='x'/></camera></cameras>"
                    "</calibration>", "r11"),
    ("bad.qca.txt", "<other/>", "not a Qualisys calibration"),
    ("bad.qca.txt", "<calibration", "not valid XML"),
    ("bad.yml", "not: [a yaml storage", "OpenCV FileStorage"),
    ("bad.yml", "%YAML:1.0\n---\nnames: [a]\n", "K_a"),
    ("bad.txt", "", "unknown calibration format"),
])
def test_bad_calibration_files_are_one_line_naming_the_file(tmp_path, capfd, name, text, problem):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError, match=problem) as err:
        read_rig(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)
    assert capfd.readouterr().err == ""  # no library messages before the line
