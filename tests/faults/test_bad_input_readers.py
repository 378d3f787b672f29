"""Bad input to the file readers of data_tools: one regression test per class of failure the bad-input corpus
found (reader side).

Every refusal is one :class:`InputError` naming the file (and line or key) and
the expected range; harmless variants (byte-order marks, tabs, greyscale, one
frame) are accepted. The small valid files built here are also the seeds of
tests/faults/test_fuzz_readers.py.
"""
from __future__ import annotations

import json
import signal
import struct
import zlib
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np
import pytest

from data_tools.motion.asf_amc import AsfSkeleton, asf_amc_clip, read_asf
from data_tools.motion.bvh import bvh_clip
from data_tools.motion.clip_io import load_converted_clip
from data_tools.motion.retarget import retarget
from data_tools.samples import sample_walks
from data_tools.sequences.bodytrack import bodytrack_model, read_poses
from data_tools.sequences.calibration import read_bodytrack_calibration, read_cameras_json
from data_tools.sequences.sequence import (
    frame_path, read_groundtruth, read_image, read_mask, read_sequence, write_groundtruth, write_image,
    write_sequence_header,
)
from tracker.core.body import default_shape
from tracker.core.cameras import CameraRig, look_at
from tracker.core.errors import InputError
from tracker.core.rotations import matrix_to_exp_map

SAMPLE_ASF, SAMPLE_AMCS = sample_walks()


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    """OpenCV on one thread: the machine is shared, and decoding tiny files gains nothing from more."""
    old = cv2.getNumThreads()
    cv2.setNumThreads(1)
    yield
    cv2.setNumThreads(old)


@contextmanager
def time_limit(seconds: float):
    """Fail (TimeoutError) instead of hanging when the body runs longer than ``seconds``."""
    def expire(signum, frame):
        raise TimeoutError(f"still running after {seconds} s (a hang?)")

    if not hasattr(signal, "SIGALRM"):  # not on Windows: no per-case limit there
        yield
        return
    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def refused(call, *fragments: str, seconds: float = 10.0) -> InputError:
    """Run ``call``; it must raise a one-line :class:`InputError` containing every fragment."""
    with time_limit(seconds), pytest.raises(InputError) as err:
        call()
    text = str(err.value)
    assert "\n" not in text, text
    for f in fragments:
        assert f in text, (f, text)
    return err.value


# ---------------------------------------------------------------------------
# Small valid files (also the seeds of the fuzz tests)
# ---------------------------------------------------------------------------

def amc_lines(frames: int = 3) -> list[str]:
    """The header and first ``frames`` frames of the shipped walk 07_01."""
    lines = SAMPLE_AMCS[0].read_text().splitlines()
    return lines[:lines.index(str(frames + 1))]


def asf_lines() -> list[str]:
    return SAMPLE_ASF.read_text().splitlines()


TINY_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Chest
  {
    OFFSET 0 50 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT Head
    {
      OFFSET 0 60 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {
        OFFSET 0 20 0
      }
    }
  }
  JOINT LeftHip
  {
    OFFSET 10 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT LeftKnee
    {
      OFFSET 0 -45 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {
        OFFSET 0 -45 0
      }
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0083333
1 90 2 0 0 0 1 2 3 0 0 0 4 5 6 7 8 9
2 91 2 0 1 0 1 2 3 0 0 0 4 5 6 7 8 9
3 92 2 0 2 0 1 2 3 0 0 0 4 5 6 7 8 9
"""


def write_lines(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


def tiny_rig(views: int = 2, width: int = 32, height: int = 24) -> CameraRig:
    return CameraRig([look_at(f"cam{v}", (3000 * np.cos(v), 3000 * np.sin(v), 1500), (0, 0, 1000), width, height,
                              30.0) for v in range(views)])


def tiny_meta() -> dict:
    return {"source": "test", "fps": 60.0, "body_shape": default_shape().to_dict()}


def tiny_sequence(root: Path, frames: int = 2, views: int = 2, width: int = 32, height: int = 24,
                  grey: bool = False) -> Path:
    """An own-layout sequence of flat images (no rendering): cameras.json, meta.json, plates, ground truth."""
    rig = tiny_rig(views, width, height)
    write_sequence_header(root, rig, tiny_meta())
    shape = (height, width) if grey else (height, width, 3)
    for cam in rig.cameras:
        write_image(root / "background" / f"{cam.name}.png", np.full(shape, 90, np.uint8))
        for k in range(frames):
            write_image(frame_path(root, cam.name, k), np.full(shape, 100 + k, np.uint8))
    write_groundtruth(root, np.zeros((frames, 40)), np.zeros((frames, 15, 3)), 60.0)
    return root


def cal_text(cam) -> str:
    """A PARSEC ``CameraK.cal`` for ``cam``: fc, cc, alpha, kc, R (row-major), T, om, one number a line."""
    numbers = [cam.fx, cam.fy, cam.cx, cam.cy, cam.skew, *cam.dist, *np.ravel(cam.R), *cam.t,
               *matrix_to_exp_map(cam.R)]
    return "".join(f"{x:.10f}\r\n" for x in numbers)


BODY_SHAPE_TXT = "".join(f"{x}\n" for x in [60.0, 50.0, 1.0, 1.0] * 10 + [300.0] * 18)
POSE_TXT = " ".join(["0.0"] * 3 + ["100", "200", "900"] + ["0.1"] * 25) + "\n"
POSE_PARAMETERS_TXT = "".join(f"{x}\n" for x in [0.01] * 31 + [-1e4] * 31 + [1e4] * 31)


def tiny_bodytrack(root: Path, views: int = 3) -> Path:
    """A PARSEC bodytrack folder (640 x 480 BMPs, one frame) with ``views`` calibrated cameras."""
    (root / "CALIB").mkdir(parents=True)
    for k, cam in enumerate(tiny_rig(views, 640, 480).cameras, start=1):
        (root / "CALIB" / f"Camera{k}.cal").write_text(cal_text(cam))
        for prefix, value in (("CAM", 80), ("FG", 0)):
            (root / f"{prefix}{k}").mkdir()
            img = np.full((480, 640), value, np.uint8)
            img[200:300, 300:340] = 255
            cv2.imwrite(str(root / f"{prefix}{k}" / "image0000.bmp"), img)
    (root / "BodyShapeParameters.txt").write_text(BODY_SHAPE_TXT)
    (root / "InitialPose.txt").write_text(POSE_TXT)
    (root / "PoseParameters.txt").write_text(POSE_PARAMETERS_TXT)
    return root


# ---------------------------------------------------------------------------
# 1. Hang: ASF hierarchies that are not trees
# ---------------------------------------------------------------------------

def _hierarchy_case(case: str) -> tuple[list[str], int]:
    """The sample skeleton with one hierarchy fault, and the line (1-based) that must be named."""
    lines = asf_lines()
    row = {s.split()[0]: i for i, s in enumerate(lines) if s.split()[:1] and i > lines.index(":hierarchy")}
    if case == "two parents":
        lines[row["ltibia"]] += " lfemur"
        return lines, row["ltibia"] + 1
    if case == "root as child":
        lines[row["lfemur"]] += " root"
        return lines, row["lfemur"] + 1
    if case == "self loop":
        lines[row["lfemur"]] += " lfemur"
        return lines, row["lfemur"] + 1
    # A cycle cut off from the root: lhipjoint leaves the root's children and hangs below its own foot.
    lines[row["root"]] = lines[row["root"]].replace(" lhipjoint", "")
    lines.insert(row["ltibia"] + 1, "    lfoot lhipjoint")
    return lines, row["lhipjoint"] + 1


@pytest.mark.parametrize("case, message", [("two parents", "has two parents"), ("root as child", "root as a child"),
                                           ("self loop", "has two parents"), ("cycle", "not connected to the root")])
def test_asf_hierarchy_not_a_tree_is_refused_quickly(tmp_path, case, message):
    lines, line = _hierarchy_case(case)
    path = write_lines(tmp_path / "07.asf", lines)
    err = refused(lambda: read_asf(path), message, seconds=5)
    assert err.path == str(path) and err.line == line


def test_skeleton_order_stops_on_a_cycle():
    skel = read_asf(SAMPLE_ASF)
    skel.children["lfoot"] = ["lfemur"]  # built by hand, bypassing the parser's checks
    with time_limit(5), pytest.raises(InputError, match="twice"):
        skel.order()
    assert isinstance(skel, AsfSkeleton)


# ---------------------------------------------------------------------------
# 2. Text that is not UTF-8; byte-order marks, tabs and deep JSON
# ---------------------------------------------------------------------------

def _text_families(tmp_path: Path) -> dict[str, tuple[Path, object]]:
    """Each text family: (file holding valid text, reader of that file)."""
    seq = tiny_sequence(tmp_path / "seq")
    bt = tiny_bodytrack(tmp_path / "bt")
    asf = write_lines(tmp_path / "07.asf", asf_lines())
    amc = write_lines(tmp_path / "07_01.amc", amc_lines())
    bvh = tmp_path / "tiny.bvh"
    bvh.write_text(TINY_BVH)
    return {
        "cameras.json": (seq / "cameras.json", lambda: read_cameras_json(seq / "cameras.json")),
        "meta.json": (seq / "meta.json", lambda: read_sequence(seq)),
        ".cal": (bt / "CALIB" / "Camera1.cal", lambda: read_bodytrack_calibration(bt / "CALIB" / "Camera1.cal")),
        "body shape": (bt / "BodyShapeParameters.txt", lambda: bodytrack_model(bt)),
        "pose": (bt / "InitialPose.txt", lambda: read_poses(bt / "InitialPose.txt")),
        "asf": (asf, lambda: read_asf(asf)),
        "amc": (amc, lambda: asf_amc_clip(asf, amc)),
        "bvh": (bvh, lambda: bvh_clip(bvh)),
    }


FAMILIES = ["cameras.json", "meta.json", ".cal", "body shape", "pose", "asf", "amc", "bvh"]


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("encoding", ["latin-1", "utf-16", "binary"])
def test_text_that_is_not_utf8_is_refused(tmp_path, family, encoding):
    path, read = _text_families(tmp_path)[family]
    text = path.read_text()
    if encoding == "latin-1":  # an e-acute at the end of the first line, as a Latin-1 editor saves it
        first, rest = text.split("\n", 1)
        data = (first + " é\n" + rest).encode("latin-1")
    elif encoding == "utf-16":
        data = text.encode("utf-16")
    else:
        data = bytes(np.random.default_rng(0).integers(0, 256, 300, dtype=np.uint8))
    path.write_bytes(data)
    err = refused(read, "not UTF-8 text")
    assert err.path == str(path)


@pytest.mark.parametrize("family", FAMILIES)
def test_utf8_byte_order_mark_is_accepted(tmp_path, family):
    path, read = _text_families(tmp_path)[family]
    plain = read()
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    with_bom = read()
    assert type(with_bom) is type(plain)


def test_bvh_with_tabs_is_accepted(tmp_path):
    plain = tmp_path / "plain.bvh"
    plain.write_text(TINY_BVH)
    tabbed = tmp_path / "tabbed.bvh"
    tabbed.write_text(TINY_BVH.replace("  ", "\t").replace("Frame Time:", "Frame\tTime:\t").replace(" ", "\t"))
    assert np.array_equal(bvh_clip(tabbed).positions, bvh_clip(plain).positions)


def test_deeply_nested_json_is_refused(tmp_path):
    path = tmp_path / "cameras.json"
    path.write_text("[" * 100000 + "]" * 100000)
    refused(lambda: read_cameras_json(path), "nested too deeply", "cameras.json")


# ---------------------------------------------------------------------------
# 3. .npz files: ground truth and converted clips
# ---------------------------------------------------------------------------

def _valid_arrays(T: int = 3) -> dict[str, np.ndarray]:
    return {"poses": np.zeros((T, 40)), "markers": np.zeros((T, 15, 3)), "fps": np.float64(60.0)}


NPZ_CASES = {
    "empty file": (b"", "cannot read ground truth"),
    "not a zip": (b"poses = 1 2 3\n", "cannot read ground truth"),
    "fps 1-d": ({"fps": np.array([60.0, 30.0])}, "fps must have shape ()"),
    "fps text": ({"fps": np.array("sixty")}, "fps must be real numbers, got text"),
    "fps zero": ({"fps": np.float64(0.0)}, "fps = 0 is outside the plausible range (expected positive"),
    "poses text": ({"poses": np.full((3, 40), "a")}, "poses must be real numbers, got text"),
    "poses complex": ({"poses": np.zeros((3, 40), complex)}, "poses must be real numbers, got complex"),
    "poses object": ({"poses": np.array([None] * 3, dtype=object)}, "cannot read ground truth"),
    "poses shape": ({"poses": np.zeros((3, 39))}, "poses must have shape T x 40"),
    "poses zero rows": ({"poses": np.zeros((0, 40)), "markers": np.zeros((0, 15, 3))}, "at least 1"),
    "poses NaN": ({"poses": np.full((3, 40), np.nan)}, "poses[0, 0]: NaN or infinite value"),
    "poses 1e308": ({"poses": np.full((3, 40), 1e308)}, "poses[0, 0] = 1e+308 is outside the plausible range"),
    "markers 2e6 mm": ({"markers": np.full((3, 15, 3), 2e6)}, "within ±1e+06 mm"),
    "markers frames": ({"markers": np.zeros((4, 15, 3))}, "markers must have shape T (3) x 15 x 3"),
    "lacks markers": ({"markers": None}, "lacks markers"),
}


def _write_npz(path: Path, spec) -> None:
    if isinstance(spec, bytes):
        path.write_bytes(spec)
        return
    arrays = _valid_arrays()
    arrays.update(spec)
    np.savez(path, **{k: v for k, v in arrays.items() if v is not None})


@pytest.mark.parametrize("case", list(NPZ_CASES))
def test_bad_groundtruth_npz_is_refused(tmp_path, case):
    spec, message = NPZ_CASES[case]
    path = tmp_path / "groundtruth.npz"
    _write_npz(path, spec)
    err = refused(lambda: read_groundtruth(path, 40), message)
    assert err.path == str(path)


def test_truncated_groundtruth_npz_is_refused(tmp_path):
    path = tmp_path / "groundtruth.npz"
    _write_npz(path, {})
    data = path.read_bytes()
    for cut in (10, len(data) // 2, len(data) - 5):
        path.write_bytes(data[:cut])
        refused(lambda: read_groundtruth(path, 40), "cannot read ground truth")
    np.save(tmp_path / "single.npy", np.zeros(3))
    (tmp_path / "single.npy").rename(path)
    refused(lambda: read_groundtruth(path, 40), "single .npy array")


@pytest.mark.parametrize("key, value, message", [
    ("fps", np.array("x"), "fps must be real numbers"),
    ("model_markers", np.full((3, 15, 3), 1e308), "model_markers[0, 0, 0] = 1e+308"),
    ("shape", np.array('{"lengths": "long"}'), "body shape lengths must be an object"),
    ("shape", np.array("[" * 5000 + "]" * 5000), "nested too deeply"),
    ("dof_names", np.zeros(3), "dof_names must be a list of strings"),
])
def test_bad_converted_clip_is_refused(tmp_path, key, value, message):
    arrays = _valid_arrays()
    arrays.update(model_markers=np.zeros((3, 15, 3)), shape=np.array(default_shape().to_json()))
    path = tmp_path / "clip.npz"
    np.savez(path, **{**arrays, key: value})
    err = refused(lambda: load_converted_clip(path), message)
    assert err.path == str(path)
    np.savez(path, **arrays)
    assert load_converted_clip(path).n_frames == 3


# ---------------------------------------------------------------------------
# 4. meta.json and cameras.json values
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("mutate, message", [
    (lambda m: m["body_shape"]["lengths"].update(torso="480"), "body shape lengths[torso] must be a number"),
    (lambda m: m["body_shape"]["lengths"].update(torso=[480]), "body shape lengths[torso] must be a number"),
    (lambda m: m["body_shape"].update(radius_distal="thin"), "radius_distal must be an object"),
    (lambda m: m["body_shape"].update(left_hip_offset="0 90 -80"), "left_hip_offset must be a list of 3 numbers"),
    (lambda m: m["body_shape"]["lengths"].update(torso=1e308), "at most 5000 mm"),
    (lambda m: m.update(body_shape=[1, 2]), "body shape must be a JSON object"),
    (lambda m: m.update(fps="60"), "fps must be a number"),
    (lambda m: m.update(fps=1e308), "at most 100000 Hz"),
])
def test_bad_meta_json_is_refused(tmp_path, mutate, message):
    root = tiny_sequence(tmp_path / "seq")
    meta = tiny_meta()
    mutate(meta)
    (root / "meta.json").write_text(json.dumps(meta))
    err = refused(lambda: read_sequence(root), message)
    assert err.path == str(root / "meta.json")


@pytest.mark.parametrize("field, value, message", [
    ("fx", 1e308, "fx = 1e+308 is outside the plausible range (expected positive and at most 1e+06 px)"),
    ("width", 1e308, "width = 1e+308 is outside the plausible range (expected positive and at most 20000 px)"),
    ("width", 30000, "at most 20000 px"),
    ("height", 0, "positive integers"),
    ("width", 2.5, "positive integers"),
    ("width", "640", "width must be a number"),
    ("width", 10 ** 400, "width"),
    ("cx", 1e308, "cx = 1e+308"),
    ("t", [0, 0, 1e308], "within ±1e+06 mm"),
    ("R", [[1e308, 0, 0], [0, 1, 0], [0, 0, 1]], "within ±2"),
    ("R", [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]], "not a rotation"),
    ("dist", [1e308, 0, 0, 0, 0], "dist"),
    ("name", "../evil", "camera name must be"),
    ("name", ["cam0"], "camera name must be"),
])
def test_bad_cameras_json_values_are_refused(tmp_path, field, value, message):
    cam = tiny_rig(1).cameras[0].to_dict()
    cam[field] = value
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps({"cameras": [cam]}))
    err = refused(lambda: read_cameras_json(path), message)
    assert err.path == str(path)


def test_implausible_cal_values_are_refused(tmp_path):
    path = tmp_path / "Camera1.cal"
    numbers = cal_text(tiny_rig(1, 640, 480).cameras[0]).split()
    numbers[0] = "1e308"
    path.write_text("\n".join(numbers))
    refused(lambda: read_bodytrack_calibration(path), "fx = 1e+308", "Camera1.cal")


# ---------------------------------------------------------------------------
# 5. Mocap values and one-frame clips
# ---------------------------------------------------------------------------

def test_amc_root_position_1e300_is_refused(tmp_path):
    lines = amc_lines()
    k = next(i for i, s in enumerate(lines) if s.startswith("root"))
    lines[k] = "root 1e300 1e300 1e300 0 0 0"
    amc = write_lines(tmp_path / "07_01.amc", lines)
    err = refused(lambda: asf_amc_clip(SAMPLE_ASF, amc), "root position", "within ±1e+06 mm")
    assert err.line == k + 1


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("OFFSET 0 50 0", "OFFSET 0 1e300 0"), "OFFSET = 1e+300"),
    (lambda t: t.replace("\n1 90 2", "\n1e300 90 2"), "frame values[0, 0] = 1e+300"),
    (lambda t: t.replace("Frame Time: 0.0083333", "Frame Time: 1e-300"), "at most 100000 Hz"),
])
def test_bvh_absurd_values_are_refused(tmp_path, edit, message):
    path = tmp_path / "x.bvh"
    path.write_text(edit(TINY_BVH))
    refused(lambda: bvh_clip(path), message, "x.bvh")


def test_asf_absurd_units_and_lengths_are_refused(tmp_path):
    lines = asf_lines()
    k = next(i for i, s in enumerate(lines) if s.strip().startswith("length") and i < 20)
    bad = list(lines)
    bad[k] = "  length 1e-300"
    refused(lambda: read_asf(write_lines(tmp_path / "07.asf", bad)), "units length", f"07.asf:{k + 1}:")
    bad = list(lines)
    j = next(i for i, s in enumerate(lines) if s.strip().startswith("length") and i > 20)
    bad[j] = "     length 1e300"
    refused(lambda: read_asf(write_lines(tmp_path / "07.asf", bad)), "length = 5.64444e+301", "within [0, 5000] mm")


def test_one_frame_clips_convert(tmp_path):
    amc = write_lines(tmp_path / "07_01.amc", amc_lines(1))
    bvh = tmp_path / "one.bvh"
    bvh.write_text(TINY_BVH.replace("Frames: 3", "Frames: 1").rsplit("\n2 91", 1)[0] + "\n")
    for clip in (asf_amc_clip(SAMPLE_ASF, amc), bvh_clip(bvh)):
        assert clip.n_frames == 1 and np.all(np.isfinite(clip.positions))
    result = retarget(asf_amc_clip(SAMPLE_ASF, amc), fps=60)
    assert result.poses.shape == (1, 40) and np.all(np.isfinite(result.poses)) and result.mean_residual < 20


# ---------------------------------------------------------------------------
# 6. Images and masks
# ---------------------------------------------------------------------------

def _png_claiming(width: int, height: int) -> bytes:
    """A PNG whose header (with a correct checksum) claims ``width`` x ``height`` pixels."""
    data = bytearray(cv2.imencode(".png", np.zeros((24, 32), np.uint8))[1].tobytes())
    data[16:24] = struct.pack(">II", width, height)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    return bytes(data)


def _bmp_claiming(width: int, height: int) -> bytes:
    data = bytearray(cv2.imencode(".bmp", np.zeros((24, 32, 3), np.uint8))[1].tobytes())
    data[18:26] = struct.pack("<ii", width, height)
    return bytes(data)


GOOD_PNG = cv2.imencode(".png", np.full((24, 32, 3), 7, np.uint8))[1].tobytes()


def _png_with_bad_data() -> bytes:
    """GOOD_PNG with its compressed pixels scrambled but every checksum recomputed (libpng itself must object)."""
    data = bytearray(GOOD_PNG)
    pos = 8
    while True:
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if kind == b"IDAT":
            for k in range(2, length):
                data[pos + 8 + k] ^= 0x55
            crc = zlib.crc32(bytes(data[pos + 4:pos + 8 + length]))
            data[pos + 8 + length:pos + 12 + length] = struct.pack(">I", crc)
            return bytes(data)
        pos += 12 + length

IMAGE_CASES = {
    "png claims 100000x100000": (_png_claiming(100000, 100000), "image is 100000x100000 pixels but its camera"),
    "png claims 32x25": (_png_claiming(32, 25), "image is 32x25 pixels but its camera is 32x24"),
    "bmp claims 200000x200000": (_bmp_claiming(200000, 200000), "image is 200000x200000 pixels"),
    "png truncated": (GOOD_PNG[:len(GOOD_PNG) // 2], "cannot read image"),
    "png bit flip": (GOOD_PNG[:40] + bytes([GOOD_PNG[40] ^ 0xFF]) + GOOD_PNG[41:], "cannot read image: corrupt PNG"),
    "png bad data, good checksums": (_png_with_bad_data(), "cannot read image"),
    "bmp truncated": (_bmp_claiming(32, 24)[:300], "cannot read image"),
    "text": (b"not an image at all", "cannot read image"),
    "empty": (b"", "cannot read image"),
}


@pytest.mark.parametrize("case", list(IMAGE_CASES))
def test_bad_images_are_refused_without_library_noise(tmp_path, capfd, case):
    data, message = IMAGE_CASES[case]
    path = tmp_path / "000000.png"
    path.write_bytes(data)
    capfd.readouterr()
    err = refused(lambda: read_image(path, 32, 24), message)
    refused(lambda: read_mask(path, 32, 24), message)
    assert err.path == str(path)
    out, errout = capfd.readouterr()
    assert out == "" and errout == "", errout


def test_mask_of_the_wrong_size_is_refused(tmp_path):
    path = tmp_path / "mask.bmp"
    cv2.imwrite(str(path), np.full((24, 30), 255, np.uint8))
    refused(lambda: read_mask(path, 32, 24), "image is 30x24 pixels but its camera is 32x24", "mask.bmp")


def test_greyscale_images_and_plates_work(tmp_path):
    seq = read_sequence(tiny_sequence(tmp_path / "grey", grey=True))
    image, plate = seq.image(1, 0), seq.background(0)
    assert image.shape == plate.shape == (24, 32, 3) and image.dtype == np.uint8
    assert np.all(image == 101) and np.all(plate == 90)
    root = tiny_sequence(tmp_path / "mixed")  # colour frames, greyscale plate
    write_image(root / "background" / "cam1.png", np.full((24, 32), 90, np.uint8))
    seq = read_sequence(root)
    assert seq.background(1).shape == seq.image(0, 1).shape == (24, 32, 3)


# ---------------------------------------------------------------------------
# 7. Missing calibrations and foreign skeletons
# ---------------------------------------------------------------------------

def test_bodytrack_camera_without_calibration_is_refused(tmp_path):
    root = tiny_bodytrack(tmp_path / "bt")
    assert read_sequence(root).n_views == 3
    (root / "CALIB" / "Camera3.cal").unlink()
    refused(lambda: read_sequence(root), "CAM3/ has images but CALIB/Camera3.cal is missing")
    (root / "CALIB" / "Camera2.cal").rename(root / "CALIB" / "Camera3.cal")
    refused(lambda: read_sequence(root), "CAM2/ has images but CALIB/Camera2.cal is missing")


def test_shared_bodytrack_missing_calibration_is_refused(bodytrack_dir, tmp_path):
    root = tmp_path / "B"
    (root / "CALIB").mkdir(parents=True)
    for name in ("BodyShapeParameters.txt", "InitialPose.txt", "PoseParameters.txt"):
        (root / name).write_bytes((bodytrack_dir / name).read_bytes())
    for k in (1, 2, 3, 4):
        if k != 4:
            (root / "CALIB" / f"Camera{k}.cal").write_bytes((bodytrack_dir / "CALIB" / f"Camera{k}.cal").read_bytes())
        for prefix in ("CAM", "FG"):
            (root / f"{prefix}{k}").mkdir()
            for f in (bodytrack_dir / f"{prefix}{k}").iterdir():
                (root / f"{prefix}{k}" / f.name).write_bytes(f.read_bytes())
    refused(lambda: read_sequence(root), "CAM4/ has images but CALIB/Camera4.cal is missing")


def test_skeleton_of_another_subject_is_refused(tmp_path):
    amc = write_lines(tmp_path / "07_01.amc", amc_lines())
    foreign = write_lines(tmp_path / "02.asf", asf_lines())
    refused(lambda: asf_amc_clip(foreign, amc), "motion of CMU subject 07 paired with the skeleton of subject 02")
    # A skeleton whose bones disagree with the motion's: fewer dofs, or bones the motion never names.
    lines = asf_lines()
    k = next(i for i, s in enumerate(lines) if s.strip() == "name lfemur")
    dof = next(i for i in range(k, len(lines)) if lines[i].strip().startswith("dof"))
    lines[dof] = "    dof rx ry"
    refused(lambda: asf_amc_clip(write_lines(tmp_path / "07.asf", lines), amc), "gives it 2 dof",
            "this motion's skeleton")
    lines = asf_lines()
    lines[k] = "    name lthigh"
    lines = [s.replace(" lfemur", " lthigh") if s.split()[:1] in (["lhipjoint"], ["lfemur"]) else s for s in lines]
    lines = [s.replace("lfemur ", "lthigh ") if s.split()[:1] == ["lfemur"] else s for s in lines]
    refused(lambda: asf_amc_clip(write_lines(tmp_path / "07.asf", lines), amc), "'lfemur' is not in the skeleton")


# -- output paths (checked before any work) and nothing half-written -------------------------------------------

@pytest.mark.slow
def test_output_paths_are_refused_before_any_work(tmp_path):
    import subprocess
    import sys

    from data_tools.samples import sample_walks

    asf, walks = sample_walks()
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    full = tmp_path / "full"
    full.mkdir()
    (full / "something").write_text("x")
    cases = [
        (["convert", "--mocap", str(walks[0]), "--out", str(a_file / "c.npz")], "is a file, not a folder"),
        (["convert", "--mocap", str(walks[0]), "--out", str(tmp_path)], "must end in .npz"),
        (["synth", "--mocap", str(walks[0]), "--out", str(full), "--frames", "2"], "not empty"),
        (["synth", "--mocap", str(walks[0]), "--out", str(a_file), "--frames", "2"], "is a file"),
        (["train", "--prior", "crbm", "--mocap", str(walks[0]), "--out", str(full)], "is a folder"),
        (["track", str(full), "--prior", "zero-velocity", "--out", str(a_file)], "is a file, not a folder"),
    ]
    for args, expected in cases:
        r = subprocess.run([sys.executable, "-m", "tracker", *args], capture_output=True, text=True)
        err = r.stderr.strip()
        assert r.returncode == 2 and expected in err and "\n" not in err and "Traceback" not in err, (args, err)
    assert sorted(p.name for p in full.iterdir()) == ["something"] and a_file.read_text() == "x"


@pytest.mark.slow
def test_synth_replaces_a_folder_only_with_overwrite_and_whole(tmp_path):
    from data_tools.motion.load import load_mocap
    from data_tools.motion.retarget import retarget
    from data_tools.samples import sample_walks
    from data_tools.synthesis.synth import SynthConfig, synthesize

    asf, walks = sample_walks()
    clip = retarget(load_mocap(walks[0], asf), fps=60.0)
    synthesize(clip, tmp_path / "s", SynthConfig(frames=3, views=1, width=160, height=120))
    with pytest.raises(InputError, match="not empty"):
        synthesize(clip, tmp_path / "s", SynthConfig(frames=2, views=1, width=160, height=120))
    synthesize(clip, tmp_path / "s", SynthConfig(frames=2, views=1, width=160, height=120), overwrite=True)
    assert len(list((tmp_path / "s" / "images" / "cam0").iterdir())) == 2  # the old 3 frames are gone
    assert [p.name for p in tmp_path.iterdir()] == ["s"]  # no temporary folder left behind


def test_frame_rates_below_a_tenth_of_a_hertz_are_refused():
    from data_tools.motion.load import load_mocap
    from data_tools.motion.mocap import frame_times

    clip = load_mocap(SAMPLE_AMCS[0], SAMPLE_ASF)
    refused(lambda: frame_times(clip.n_frames, clip.fps, 1e-300), "target frame rate", "within [0.1, 100000] Hz")
    assert len(frame_times(clip.n_frames, clip.fps, 0.5)) >= 1
