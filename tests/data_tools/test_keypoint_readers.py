"""Keypoints of other tools read as they are (OpenPose-style JSON per frame, arrays), converted to a sequence's
frames and pixels, and the ``keypoints`` command; every bad file is one line naming it."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import SHARED, need_shared
from data_tools.sequences.keypoint_file import keypoints_path, read_keypoints
from data_tools.sequences.sequence import write_image, write_sequence_header
from data_tools.vision.keypoints.layouts import LAYOUT_NAMES, LAYOUTS
from data_tools.vision.keypoints.readers import import_keypoints, read_openpose_frame
from tracker.app.cli import main
from tracker.core.cameras import CameraRig, look_at
from tracker.core.errors import InputError
from tracker.core.keypoints import KEYPOINT_INDEX, KEYPOINTS

EXAMPLE = SHARED / "realvideo" / "pose2sim_static"
#: The tiny sequence: 2 cameras of W x H pixels, T frames, imported from videos shrunk by F from video frame FIRST.
W, H, T, F, FIRST = 40, 30, 4, 2.0, 3
CAMERAS = ("c0", "c1")


def make_sequence(root: Path, meta: dict | None = None) -> Path:
    """A sequence folder of blank frames whose meta.json says it was imported with downscale F from FIRST."""
    rig = CameraRig([look_at(name, (3000.0 * np.cos(a), 3000.0 * np.sin(a), 1000.0), (0.0, 0.0, 900.0), W, H, 40.0)
                     for name, a in zip(CAMERAS, (0.0, 1.5))])
    write_sequence_header(root, rig, {"fps": 30.0, "downscale": F, "first_video_frame": FIRST} if meta is None
                          else meta)
    for cam in CAMERAS:
        for k in range(T):
            write_image(root / "images" / cam / f"{k:06d}.png", np.zeros((H, W, 3), np.uint8))
    return root


@pytest.fixture
def seq(tmp_path) -> Path:
    return make_sequence(tmp_path / "seq")


def detections(rng: np.random.Generator, n_frames: int, layout: str) -> np.ndarray:
    """Random detections ``n_frames x J x 3`` of ``layout`` at the videos' full resolution (inside the image)."""
    J = len(LAYOUT_NAMES[layout])
    xy = rng.uniform(0, 1, (n_frames, J, 2)) * (W * F - 1, H * F - 1)
    return np.concatenate([xy, rng.uniform(0.2, 1.0, (n_frames, J, 1))], axis=-1)


def write_frame(folder: Path, k: int, people: list, **extra) -> Path:
    """An OpenPose-style file of the tool's frame ``k`` (people: ``J x 3`` arrays or raw lists)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"clip_{k:012d}_keypoints.json"
    listed = [{"person_id": [-1], "pose_keypoints_2d": np.asarray(p).ravel().tolist() if isinstance(p, np.ndarray)
               else p} for p in people]
    path.write_text(json.dumps({"version": 1.3, "people": listed, **extra}))
    return path


def expected(points: np.ndarray, layout: str) -> np.ndarray:
    """Detections ``(..., J, 3)`` as the body keypoints ``(..., K, 3)`` in the sequence's pixels, built from the
    layout's names (NaN and 0 where the layout lacks a keypoint)."""
    out = np.full(points.shape[:-2] + (len(KEYPOINTS), 3), np.nan)
    out[..., 2] = 0.0
    for name, keypoint in LAYOUTS[layout].items():
        j = LAYOUT_NAMES[layout].index(name)
        out[..., KEYPOINT_INDEX[keypoint], :2] = (points[..., j, :2] + 0.5) / F - 0.5
        out[..., KEYPOINT_INDEX[keypoint], 2] = points[..., j, 2]
    return out


def one_line(exc: pytest.ExceptionInfo, path: Path) -> str:
    """The refusal's text, checked to be one line naming ``path``."""
    text = str(exc.value)
    assert "\n" not in text and exc.value.path == str(path), text
    return text


# -- OpenPose JSON ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_openpose_json_of_each_layout_comes_back_in_body_keypoint_order(seq, tmp_path, layout):
    rng = np.random.default_rng(7)
    n_tool = FIRST + T + 2  # the tool saw frames before and after the sequence's
    truth = {cam: detections(rng, n_tool, layout) for cam in CAMERAS}
    folders = []
    for cam in CAMERAS:
        folder = tmp_path / f"{cam}_json"
        for k in range(n_tool):
            if cam == "c1" and k == FIRST + 1:
                continue  # no file: a frame the tool skipped
            people = [truth[cam][k]]
            if k == FIRST + 2:
                people = [0.5 * truth[cam][k] * (1, 1, 0.5), truth[cam][k]]  # a weaker person listed first
            if cam == "c0" and k == FIRST + 3:
                people = []  # nobody found
            write_frame(folder, k, people)
        folders.append(str(folder))
    given = layout if layout in ("body_25", "body_25b") else None  # 17, 26 and 33 points are inferred
    kp = import_keypoints(seq, folders, given)
    assert kp.points.shape == (T, 2, len(KEYPOINTS), 3) and kp.cameras == CAMERAS
    want = np.stack([expected(truth[cam][FIRST:FIRST + T], layout) for cam in CAMERAS], axis=1)
    want[1, 1] = (np.nan, np.nan, 0.0)
    want[3, 0] = (np.nan, np.nan, 0.0)
    np.testing.assert_allclose(kp.points, want, atol=1e-9)
    assert kp.source["detector"] == "openpose-json" and kp.source["version"] == 1.3
    assert kp.source["layout"] == layout
    assert [f["files"] for f in kp.source["files"]] == [T, T - 1]  # files outside the sequence are not read
    back = read_keypoints(seq, CAMERAS, T)
    np.testing.assert_allclose(back.points, kp.points)
    assert back.source == kp.source


@pytest.mark.shared
def test_real_pose2sim_files_are_body_25b(tmp_path):
    """Pose2Sim's BODY_25B files of the example (another take than its videos: pixels only, no image check)."""
    from data_tools.sequences.rig_formats import read_rig
    from data_tools.vision.video import VideoInfo, fitted_camera

    pose = need_shared(EXAMPLE / "pose")
    rig = read_rig(EXAMPLE / "Calib_qualisys.toml")
    fitted = CameraRig([fitted_camera(c, VideoInfo(Path("v.mp4"), c.width, c.height, 60.0, 12), 8.0)
                        for c in rig.cameras])
    root = tmp_path / "example"
    write_sequence_header(root, fitted, {"fps": 60.0, "downscale": 8.0, "first_video_frame": 2})
    for cam in fitted.cameras:
        for k in range(10):
            write_image(root / "images" / cam.name / f"{k:06d}.png", np.zeros((cam.height, cam.width, 3), np.uint8))
    folders = [pose / f"cam0{i}_json" for i in range(1, 5)]
    with pytest.raises(InputError, match="body_25 or body_25b") as exc:
        import_keypoints(root, folders, write=False)
    assert exc.value.path.endswith(".json") and "\n" not in str(exc.value)
    kp = import_keypoints(root, folders, "body_25b", write=False)
    assert kp.points.shape == (10, 4, len(KEYPOINTS), 3) and kp.source["version"] == 1.3
    raw, _, _ = read_openpose_frame(sorted((pose / "cam02_json").glob("*.json"))[2 + 5], "body_25b")
    neck = raw[LAYOUT_NAMES["body_25b"].index("Neck")]
    np.testing.assert_allclose(kp.points[5, 1, KEYPOINT_INDEX["neck"]], [*((neck[:2] + 0.5) / 8 - 0.5), neck[2]])
    assert (kp.confidence > 0).mean() > 0.8


def test_malformed_json_files_are_refused_naming_the_file(seq, tmp_path):
    rng = np.random.default_rng(1)
    good = detections(rng, 1, "coco_17")[0]
    cases = {
        "bad json": lambda f: f.write_text("{\"people\": [1, 2"),
        "no people": lambda f: f.write_text(json.dumps({"version": 1.3})),
        "wrong count": lambda f: f.write_text(json.dumps({"people": [{"pose_keypoints_2d": [1.0] * 18 * 3}]})),
        "not numbers": lambda f: f.write_text(json.dumps({"people": [{"pose_keypoints_2d": ["x"] * 17 * 3}]})),
        "confidence": lambda f: f.write_text(json.dumps({"people": [{"pose_keypoints_2d": (good * (1, 1, 3))
                                                                     .ravel().tolist()}]})),
        "negative": lambda f: f.write_text(json.dumps({"people": [{"pose_keypoints_2d": (good * (1, 1, -1))
                                                                   .ravel().tolist()}]})),
    }
    reasons = {"bad json": "not valid JSON", "no people": "no 'people' list", "wrong count": "18 points per person",
               "not numbers": "is not a number", "confidence": "outside [0, 1]", "negative": "outside [0, 1]"}
    for name, spoil in cases.items():
        folders = []
        for cam in CAMERAS:
            folder = tmp_path / name / cam
            for k in range(FIRST, FIRST + T):
                write_frame(folder, k, [good])
            folders.append(folder)
        bad = sorted(folders[1].glob("*.json"))[2]
        spoil(bad)
        with pytest.raises(InputError) as exc:
            import_keypoints(seq, folders, write=False)
        assert reasons[name] in one_line(exc, bad), name
    assert not keypoints_path(seq).exists()


def test_ambiguous_counts_and_missing_folders_are_refused(seq, tmp_path):
    rng = np.random.default_rng(2)
    folders = []
    for cam in CAMERAS:
        for k in range(FIRST, FIRST + T):
            write_frame(tmp_path / cam, k, [detections(rng, 1, "body_25")[0]])
        folders.append(tmp_path / cam)
    first = sorted(folders[0].glob("*.json"))[0]
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, folders, write=False)
    assert "body_25 or body_25b" in one_line(exc, first)
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, folders, "coco_17", write=False)
    assert "25 points per person, but the coco_17 layout has 17" in one_line(exc, first)
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [folders[0], tmp_path / "nowhere"], "body_25", write=False)
    assert "does not exist" in one_line(exc, tmp_path / "nowhere")
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [folders[0]], "body_25", write=False)
    assert "1 view(s) but the sequence has 2 cameras (c0, c1)" in one_line(exc, seq / "cameras.json")
    with pytest.raises(InputError, match="which the sequence lacks"):
        import_keypoints(seq, [f"c0={folders[0]}", f"c9={folders[1]}"], "body_25", write=False)
    (folders[1] / "other_3.json").write_text(json.dumps({"people": []}))  # a second file of frame 3
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, folders, "body_25", write=False)
    assert "two files of frame 3" in one_line(exc, folders[1])


def test_frames_outside_the_sequence_and_pixels_of_another_resolution_are_refused(seq, tmp_path):
    rng = np.random.default_rng(3)
    early, large = tmp_path / "early", tmp_path / "large"
    for k in range(FIRST):  # only frames before the sequence's first video frame
        write_frame(early, k, [detections(rng, 1, "coco_17")[0]])
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [f"c0={early}"], write=False)
    assert "files are of frames 0 to 2" in one_line(exc, early)
    for k in range(FIRST, FIRST + T):  # pixels of a video 4 times the calibrated size
        write_frame(large, k, [detections(rng, 1, "coco_17")[0] * (4, 4, 1)])
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [f"c1={large}"], write=False)
    assert "outside its 40 x 30 images" in one_line(exc, large)


# -- arrays -------------------------------------------------------------------------------------------------------

def test_array_files_npy_and_npz(seq, tmp_path):
    rng = np.random.default_rng(4)
    rows = FIRST + T
    both = np.stack([detections(rng, rows, "halpe_26") for _ in CAMERAS], axis=1)  # rows x V x J x 3
    both[FIRST, 0, 5] = np.nan  # a point not found, as arrays write it
    np.save(tmp_path / "both.npy", both)
    kp = import_keypoints(seq, [tmp_path / "both.npy"], write=False)
    want = expected(both[FIRST:], "halpe_26")
    want[0, 0, KEYPOINT_INDEX["left_shoulder"]] = (np.nan, np.nan, 0.0)
    np.testing.assert_allclose(kp.points, want, atol=1e-9)
    assert kp.source["detector"] == "array" and kp.source["version"] is None and kp.source["layout"] == "halpe_26"

    np.save(tmp_path / "one.npy", both[:, 1])  # T x J x 3 of one camera, given by name
    kp = import_keypoints(seq, [f"c1={tmp_path / 'one.npy'}"], write=False)
    np.testing.assert_allclose(kp.points[:, 1], want[:, 1], atol=1e-9)
    assert (kp.confidence[:, 0] == 0).all()  # a camera no source names has nothing

    np.savez(tmp_path / "named.npz", points=both[:, ::-1], layout="halpe_26", cameras=np.array(["c1", "c0"]))
    kp = import_keypoints(seq, [tmp_path / "named.npz"], write=False)
    np.testing.assert_allclose(kp.points, want, atol=1e-9)
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [tmp_path / "named.npz"], "coco_17", write=False)
    assert "not 'coco_17' as given" in one_line(exc, tmp_path / "named.npz")

    (tmp_path / "broken.npy").write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [tmp_path / "broken.npy"], write=False)
    assert "not an intact .npy file" in one_line(exc, tmp_path / "broken.npy")
    np.save(tmp_path / "flat.npy", both[..., :2])
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [tmp_path / "flat.npy"], write=False)
    assert "T x V x J x 3" in one_line(exc, tmp_path / "flat.npy")
    spoilt = both.copy()
    spoilt[4, 1, 2, 2] = 1.5
    np.save(tmp_path / "over.npy", spoilt)
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [tmp_path / "over.npy"], write=False)
    assert "confidence 1.5 of point 2 in row 4, view 1 is outside [0, 1]" in one_line(exc, tmp_path / "over.npy")


# -- the command --------------------------------------------------------------------------------------------------

def test_keypoints_command_writes_once_and_refuses_to_replace(seq, tmp_path, capsys):
    rng = np.random.default_rng(5)
    folders = []
    for cam in CAMERAS:
        for k in range(FIRST, FIRST + T):
            write_frame(tmp_path / f"{cam}_json", k, [detections(rng, 1, "body_25")[0]])
        folders.append(str(tmp_path / f"{cam}_json"))
    capsys.readouterr()
    assert main(["keypoints", str(seq), "--from", *folders]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "body_25 or body_25b" in err
    assert main(["keypoints", str(seq), "--from", *folders, "--layout", "body_25"]) == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith("4 frames x 2 views of keypoints (openpose-json 1.3, body_25 layout): 100% of the "
                          "keypoints found -> ") and out.endswith("keypoints.npz")
    written = read_keypoints(seq, CAMERAS, T)
    assert written.source["layout"] == "body_25"
    assert main(["keypoints", str(seq), "--from", *folders, "--layout", "body_25"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "already has keypoints (pass --overwrite" in err
    assert main(["keypoints", str(seq), "--from", f"c1={folders[0]}", "--layout", "body_25", "--overwrite"]) == 0
    replaced = read_keypoints(seq, CAMERAS, T)
    assert (replaced.confidence[:, 0] == 0).all()
    np.testing.assert_allclose(replaced.points[:, 1], written.points[:, 0])
    assert main(["keypoints", str(seq), "--from", str(tmp_path / "missing"), folders[1], "--overwrite"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"pose-tracker: error: {tmp_path / 'missing'}: keypoint folder does not exist"


def test_keypoints_command_without_from_writes_what_the_detector_finds(seq, monkeypatch, capsys):
    detect = pytest.importorskip("data_tools.vision.keypoints.detect")
    from data_tools.sequences.keypoint_file import SequenceKeypoints

    def fake(sequence, views=None, progress=None):
        points = np.full((sequence.n_frames, sequence.n_views, len(KEYPOINTS), 3), np.nan)
        points[..., 2] = 0.0
        points[:, 0, :2] = (10.0, 12.0, 0.9)  # the nose and the left ear in the first camera
        for done in range(1, 3):
            progress(done, 2)
        return SequenceKeypoints(points, sequence.rig.names, {"detector": "fake", "version": None,
                                                              "layout": "coco_17"})

    monkeypatch.setattr(detect, "detect_sequence_keypoints", fake)
    capsys.readouterr()
    assert main(["keypoints", str(seq), "--layout", "coco_17"]) == 2
    assert "--layout names the layout of files read with --from" in capsys.readouterr().err
    assert main(["keypoints", str(seq), "--quiet"]) == 0
    out = capsys.readouterr().out.strip()
    # coco_17 has 15 of the 19 body keypoints; 2 of them found in one of two views
    assert out.startswith(f"4 frames x 2 views of keypoints (fake, coco_17 layout): {100 * 2 / 30:.0f}% of the "
                          "keypoints found")
    assert read_keypoints(seq, CAMERAS, T).source["detector"] == "fake"


def test_keypoints_command_replaces_a_broken_keypoint_file(seq, tmp_path, capsys):
    """A keypoint file that cannot be read (or is of other cameras) is what --overwrite is for: the sequence is
    read without it."""
    rng = np.random.default_rng(6)
    np.save(tmp_path / "both.npy", np.stack([detections(rng, FIRST + T, "coco_17") for _ in CAMERAS], axis=1))
    keypoints_path(seq).parent.mkdir(parents=True)
    keypoints_path(seq).write_bytes(b"not a zip archive")
    assert main(["track", str(seq), "--prior", "zero-velocity", "--out", str(tmp_path / "run")]) == 2
    assert "keypoints.npz: cannot read the keypoints file" in capsys.readouterr().err
    assert main(["keypoints", str(seq), "--from", str(tmp_path / "both.npy"), "--overwrite"]) == 0
    assert read_keypoints(seq, CAMERAS, T).source["layout"] == "coco_17"


def test_keypoints_are_refused_for_a_layout_that_does_not_read_them(seq, tmp_path, monkeypatch):
    """Only this toolkit's own layout reads keypoints/keypoints.npz: another layout's would be ignored."""
    import data_tools.vision.keypoints.readers as readers
    from data_tools.sequences.sequence import read_sequence

    np.save(tmp_path / "both.npy", np.stack([detections(np.random.default_rng(7), FIRST + T, "coco_17")
                                             for _ in CAMERAS], axis=1))
    other = read_sequence(seq)
    other.layout = "bodytrack"
    monkeypatch.setattr(readers, "read_sequence", lambda root, keypoints=True: other)
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [tmp_path / "both.npy"], write=False)
    assert "this toolkit's layout only" in one_line(exc, seq)


def test_an_array_of_the_wrong_shape_is_named_with_its_own_shape(seq, tmp_path):
    np.save(tmp_path / "flat.npy", np.zeros((T, 17, 2)))
    with pytest.raises(InputError) as exc:
        import_keypoints(seq, [tmp_path / "flat.npy"], write=False)
    assert f"got shape {(T, 17, 2)}" in one_line(exc, tmp_path / "flat.npy")



def test_keypoints_leave_the_caller_s_array_as_it_was():
    from data_tools.sequences.keypoint_file import SequenceKeypoints

    points = np.ones((2, 1, len(KEYPOINTS), 3))
    points[0, 0, 0, 2] = 0.0  # not found: its pixels become NaN in the keypoints, not in the array given
    kept = points.copy()
    found = SequenceKeypoints(points, ("c0",))
    assert np.isnan(found.points[0, 0, 0, :2]).all()
    np.testing.assert_array_equal(points, kept)
