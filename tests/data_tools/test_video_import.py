"""Videos in: tiny synthetic videos of a known moving point, written with cv2.VideoWriter for a synthetic rig saved
as each calibration format, imported, and the point found where the imported cameras project it."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from data_tools.sequences.rig_formats import read_rig, write_rig
from data_tools.sequences.sequence import read_sequence
from data_tools.vision.video import import_videos, pair_videos
from tests.conftest import SHARED, need_shared
from tracker.app.cli import main
from tracker.core.cameras import CameraRig, look_at
from tracker.core.errors import InputError

EXAMPLE = SHARED / "realvideo" / "pose2sim_static"


def rig() -> CameraRig:
    """A portrait and a landscape camera."""
    return CameraRig([look_at("front", (3000.0, 0.0, 1000.0), (0.0, 0.0, 900.0), 120, 200, 150.0),
                      look_at("side", (0.0, -3000.0, 1200.0), (0.0, 0.0, 900.0), 160, 96, 120.0)])


def track_points(n: int) -> np.ndarray:
    """A point moving on a small circle, ``n x 3`` mm."""
    a = np.linspace(0, np.pi, n)
    return np.stack([300 * np.cos(a), 300 * np.sin(a), 900 + 200 * np.sin(2 * a)], axis=1)


def write_videos(folder, cams: CameraRig, n_frames=(6, 6), fps=(25.0, 25.0), names=("a.mp4", "b.mp4")):
    points = track_points(max(n_frames))
    pix, _ = cams.project(points)  # V x T x 2
    paths = []
    for v, cam in enumerate(cams.cameras):
        path = folder / names[v]
        out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps[v], (cam.width, cam.height))
        for k in range(n_frames[v]):
            img = np.full((cam.height, cam.width, 3), 30, np.uint8)
            cv2.circle(img, tuple(int(round(c * 16)) for c in pix[v, k]), 9 * 16, (255, 255, 255), -1,
                       cv2.LINE_AA, shift=4)
            out.write(img)
        out.release()
        paths.append(path)
    return paths, points


def blob_centre(image: np.ndarray) -> np.ndarray:
    grey = image.mean(axis=2)
    weight = np.clip(grey - 100, 0, None)
    ys, xs = np.indices(grey.shape)
    return np.array([(xs * weight).sum(), (ys * weight).sum()]) / weight.sum()


@pytest.mark.parametrize("calib_name, downscale", [("rig.toml", 1.0), ("rig.qca.txt", 2.0), ("rig.yml", 1.5),
                                                   ("cameras.json", 1.0)])
def test_imported_point_lies_where_the_imported_cameras_project_it(tmp_path, calib_name, downscale):
    cams = rig()
    write_rig(cams, tmp_path / calib_name)
    videos, points = write_videos(tmp_path, cams)
    result = import_videos(tmp_path / calib_name, videos, tmp_path / "seq", downscale=downscale)
    seq = read_sequence(tmp_path / "seq")
    assert seq.n_frames == 6 and seq.fps == 25.0 and seq.rig.names == ["front", "side"]
    assert (seq.rig[0].width, seq.rig[0].height) == (round(120 / downscale), round(200 / downscale))
    pix, _ = seq.rig.project(points)
    for k in range(seq.n_frames):
        for v in range(2):
            assert np.linalg.norm(blob_centre(seq.image(k, v)) - pix[v, k]) < 0.6  # px
    assert result.notes[0].startswith("front <- a.mp4 (120x200, 6 frames at 25 Hz)")


def test_frame_counts_and_rates_must_agree_or_a_range_is_chosen(tmp_path):
    cams = rig()
    write_rig(cams, tmp_path / "rig.toml")
    videos, points = write_videos(tmp_path, cams, n_frames=(6, 8))
    with pytest.raises(InputError, match=r"frame counts differ \(a.mp4 6, b.mp4 8\): .*--frames 0:6"):
        import_videos(tmp_path / "rig.toml", videos, tmp_path / "seq")
    import_videos(tmp_path / "rig.toml", videos, tmp_path / "seq", frames="2:5")
    seq = read_sequence(tmp_path / "seq")
    assert seq.n_frames == 3
    assert np.linalg.norm(blob_centre(seq.image(0, 1)) - seq.rig.project(points[2:3])[0][1, 0]) < 0.6
    with pytest.raises(InputError, match="not within 0:6"):
        import_videos(tmp_path / "rig.toml", videos, tmp_path / "seq2", frames="4:7")
    slow, _ = write_videos(tmp_path, cams, fps=(25.0, 30.0), names=("c.mp4", "d.mp4"))
    with pytest.raises(InputError, match=r"frame rates differ \(c.mp4 25 Hz, d.mp4 30 Hz\)"):
        import_videos(tmp_path / "rig.toml", slow, tmp_path / "seq3")


def test_videos_pair_with_cameras_by_name_or_mapping(tmp_path):
    videos = [tmp_path / n for n in ("cam10.mp4", "cam2.mp4", "cam1.mp4")]
    assert [p.name for p in pair_videos(["c_2", "c_1", "c_10"], videos)] == ["cam2.mp4", "cam1.mp4", "cam10.mp4"]
    assert [p.name for p in pair_videos(["x", "y", "z"], videos, {"z": "cam1.mp4", "x": "cam2.mp4"})] == \
        ["cam2.mp4", "cam1.mp4"]
    with pytest.raises(InputError, match="names 'q', which the calibration lacks"):
        pair_videos(["x"], videos, {"q": "cam1.mp4"})
    with pytest.raises(InputError, match="2 video"):
        pair_videos(["x"], videos[:2])


def test_wrong_sizes_and_bad_files_are_one_line_with_status_2(tmp_path, capsys):
    cams = rig()
    write_rig(cams, tmp_path / "rig.toml")
    swapped = CameraRig([look_at(c.name, c.centre, (0.0, 0.0, 900.0), c.height, c.width, 150.0) for c in cams])
    videos, _ = write_videos(tmp_path, swapped)
    with pytest.raises(InputError, match="turned by 90 degrees"):
        import_videos(tmp_path / "rig.toml", videos, tmp_path / "seq")
    (tmp_path / "junk.mp4").write_bytes(b"not a video")
    args = ["import-video", str(tmp_path / "junk.mp4"), str(videos[1]), "--calibration", str(tmp_path / "rig.toml"),
            "--out", str(tmp_path / "s")]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "junk.mp4" in err and "cannot open as a video" in err and len(err.splitlines()) == 1


def test_an_import_stopped_halfway_leaves_the_earlier_sequence_as_it_was(tmp_path, monkeypatch):
    import data_tools.vision.video as video

    cams = rig()
    write_rig(cams, tmp_path / "rig.toml")
    videos, _ = write_videos(tmp_path, cams)
    import_videos(tmp_path / "rig.toml", videos, tmp_path / "seq", frames="0:3")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    written = []

    def stopped_after_four(path, image):
        if len(written) == 4:
            raise KeyboardInterrupt
        written.append(path)

    monkeypatch.setattr(video, "write_image", stopped_after_four)
    with pytest.raises(KeyboardInterrupt):
        import_videos(tmp_path / "rig.toml", videos, tmp_path / "seq")
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # no staging folder either
    assert read_sequence(tmp_path / "seq").n_frames == 3



def test_an_import_over_a_sequence_drops_its_keypoints(tmp_path):
    """Keypoints are per frame and camera like images and masks: another import's frames must not keep them."""
    from data_tools.sequences.keypoint_file import SequenceKeypoints, keypoints_path, write_keypoints
    from tracker.core.keypoints import KEYPOINTS

    cams = rig()
    write_rig(cams, tmp_path / "rig.toml")
    videos, _ = write_videos(tmp_path, cams)
    import_videos(tmp_path / "rig.toml", videos, tmp_path / "seq", frames="0:3")
    write_keypoints(tmp_path / "seq", SequenceKeypoints(np.zeros((3, 2, len(KEYPOINTS), 3)), cams.names))
    import_videos(tmp_path / "rig.toml", videos, tmp_path / "seq", frames="3:6")  # as many frames, others
    assert not keypoints_path(tmp_path / "seq").exists()
    assert read_sequence(tmp_path / "seq").keypoints is None

@pytest.mark.shared
def test_example_imports_with_both_calibrations_alike(tmp_path):
    videos = sorted(need_shared(EXAMPLE).glob("cam0*.mp4"))
    a = import_videos(EXAMPLE / "Calib_qualisys.toml", videos, tmp_path / "a", downscale=8, frames="0:2")
    b = import_videos(EXAMPLE / "Calib.qca.txt", videos, tmp_path / "b", downscale=8, frames="0:2")
    assert a.fps == 60.0 and a.n_frames == 2
    # cam03 and cam04 are 8 px narrower than calibrated: padded back, so that all four views share one size
    assert [(c.width, c.height) for c in a.rig.cameras] == [(136, 240)] * 4
    seq = read_sequence(tmp_path / "b")
    assert seq.image(1, 2).shape == (240, 136, 3)  # portrait
    head = np.array([-1100.0, -100.0, 1650.0])
    assert np.abs(a.rig.project(head[None])[0] - b.rig.project(head[None])[0]).max() < 0.5  # px at 1/8 size
    assert read_rig(tmp_path / "a" / "cameras.json").names == ["cam_01", "cam_02", "cam_03", "cam_04"]
