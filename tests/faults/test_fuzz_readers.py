"""Property-based fuzzing of every file reader of data_tools: any bytes give a result or a one-line refusal.

Each test mutates a small valid file of one family (random byte flips,
truncation, deleted or repeated spans, replaced tokens; for ``.npz`` also
replaced arrays) and asserts that reading it either succeeds with finite
values or raises one one-line :class:`InputError` naming the file -- no other
exception, no Python warning, nothing printed on stdout or stderr, and no
hang (a per-case alarm on top of hypothesis's ``deadline``).

Profiles: ``ci`` (default; few examples, the file runs in well under a
minute) and ``thorough`` (``HYPOTHESIS_PROFILE=thorough``). Both are
derandomized, so a run is reproducible.
"""
from __future__ import annotations

import json
import os
import re
import warnings

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from data_tools.motion.asf_amc import asf_amc_clip  # noqa: E402
from data_tools.motion.bvh import bvh_clip  # noqa: E402
from data_tools.motion.clip_io import load_converted_clip  # noqa: E402
from data_tools.sequences.bodytrack import (  # noqa: E402
    PoseParameters, bodytrack_model, read_pose_parameters, read_poses,
)
from data_tools.sequences.calibration import (  # noqa: E402
    read_bodytrack_calibration, read_cameras_json, write_cameras_json,
)
from data_tools.sequences.sequence import read_groundtruth, read_image, read_sequence  # noqa: E402
from tests.faults.test_bad_input_readers import (  # noqa: E402
    BODY_SHAPE_TXT, POSE_PARAMETERS_TXT, POSE_TXT, SAMPLE_ASF, TINY_BVH, amc_lines, cal_text, tiny_rig,
    tiny_sequence, time_limit,
)
from tracker.core.body import default_shape  # noqa: E402
from tracker.core.errors import InputError  # noqa: E402
from tracker.core.kinematics import forward_kinematics  # noqa: E402

_COMMON = dict(derandomize=True, database=None, print_blob=False,
               suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
PROFILES = {
    "ci": settings(max_examples=100, deadline=2000, **_COMMON),
    "thorough": settings(max_examples=2000, deadline=5000, **_COMMON),
}
FUZZ = PROFILES.get(os.environ.get("HYPOTHESIS_PROFILE", "ci"), PROFILES["ci"])
#: Hard limit per case (s): hypothesis's deadline only judges cases that finish; this catches hangs.
CASE_SECONDS = 10.0

#: Replacement tokens: numbers out of range or not numbers at all, and words of the formats' grammars.
NASTY_TOKENS = [
    "nan", "inf", "-inf", "1e308", "-1e308", "1e400", "1e-320", "0", "-1", "-0", "2", "1e6", "99999999999999999999999",
    "9" * 5000, "abc", "0x10", "1_0", "٣", "²", "é", "\ufeff", "\x00", "", "{", "}", "[", "]", "[[[[", '"', ":", ",",
    "null", "true", "root", "begin", "end", ":hierarchy", ":bonedata", ":units", ":root", "ROOT", "JOINT", "End",
    "Site", "MOTION", "Frames:", "Frame Time:", "CHANNELS", "OFFSET", "HIERARCHY", "dof", "limits", "length",
    "direction", "axis", "name", "XYZ", "rx", "tx", "l",
]


class Seeds(dict):
    """The seed files by family (a short repr keeps hypothesis's failure reports readable)."""

    def __repr__(self) -> str:
        return "<fuzz seeds>"


@pytest.fixture(scope="module")
def seeds(tmp_path_factory) -> Seeds:
    """Valid files of every family, and folders whose files the tests overwrite with mutants."""
    work = tmp_path_factory.mktemp("fuzz")
    seq = tiny_sequence(work / "seq")
    write_cameras_json(tiny_rig(2), work / "cameras.json")
    bt = work / "bt"
    bt.mkdir()
    for name, text in (("BodyShapeParameters.txt", BODY_SHAPE_TXT), ("PoseParameters.txt", POSE_PARAMETERS_TXT),
                       ("InitialPose.txt", POSE_TXT)):
        (bt / name).write_text(text)
    import cv2

    rng = np.random.default_rng(0)
    colour = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    return Seeds({
        "work": work, "seq": seq, "bt": bt,
        "asf": SAMPLE_ASF.read_bytes(), "amc": ("\n".join(amc_lines(3)) + "\n").encode(), "bvh": TINY_BVH.encode(),
        "cameras.json": (work / "cameras.json").read_bytes(), "meta.json": (seq / "meta.json").read_bytes(),
        ".cal": cal_text(tiny_rig(1, 640, 480).cameras[0]).encode(),
        "bodytrack": {name: (bt / name).read_bytes() for name in
                      ("BodyShapeParameters.txt", "PoseParameters.txt", "InitialPose.txt")},
        "images": [cv2.imencode(".png", colour)[1].tobytes(), cv2.imencode(".png", colour[..., 0])[1].tobytes(),
                   cv2.imencode(".bmp", colour)[1].tobytes(), cv2.imencode(".bmp", colour[..., 0])[1].tobytes()],
        "groundtruth": (seq / "groundtruth.npz").read_bytes(),
    })


# ---------------------------------------------------------------------------
# Mutations
# ---------------------------------------------------------------------------

@st.composite
def mutant(draw, data: bytes, text: bool = True) -> bytes:
    """``data`` after one to three random edits (token replacement only for text)."""
    kinds = ["flip", "truncate", "span", "token", "token"] if text else ["flip", "truncate", "span"]
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(kinds))
        if kind == "flip" and data:
            out = bytearray(data)
            for _ in range(draw(st.integers(1, 8))):
                out[draw(st.integers(0, len(out) - 1))] ^= draw(st.integers(1, 255))
            data = bytes(out)
        elif kind == "truncate":
            data = data[:draw(st.integers(0, len(data)))]
        elif kind == "span" and data:
            a = draw(st.integers(0, len(data) - 1))
            b = draw(st.integers(a, min(len(data), a + 400)))
            data = data[:a] + data[b:] if draw(st.booleans()) else data[:b] + data[a:]  # delete or repeat
        elif kind == "token":
            data = _replace_token(draw, data)
    return data


def _replace_token(draw, data: bytes) -> bytes:
    parts = re.split(rb"(\s+|[{}\[\],:\"])", data)
    words = [i for i, p in enumerate(parts) if p and not p.isspace()]
    if not words:
        return data
    i = draw(st.sampled_from(words))
    new = draw(st.one_of(st.sampled_from(NASTY_TOKENS), st.text(max_size=6)))
    parts[i] = new.encode("utf-8", "surrogatepass") if draw(st.integers(0, 9)) else new.encode("latin-1", "replace")
    return b"".join(parts)


#: Values that may replace any node of a JSON document: wrong types, absurd numbers, NaN, huge integers.
NASTY_JSON = [None, True, "", "abc", "640", [], {}, [1, 2], [[1, 2, 3]] * 3, -1, 0, 2.5, 1e308, -1e308, 1e-320,
              10 ** 400, float("nan"), float("inf"), {"a": 1}, ["cam0"], "../x"]


@st.composite
def json_mutant(draw, data: bytes) -> bytes:
    """``data`` (JSON) with one node replaced by a :data:`NASTY_JSON` value, or deleted; still valid JSON."""
    doc = json.loads(data)
    paths: list[tuple] = []

    def walk(node, path):
        paths.append(path)
        for key, child in (node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list)
                           else ()):
            walk(child, path + (key,))

    walk(doc, ())
    path = draw(st.sampled_from(paths))
    value = draw(st.sampled_from(NASTY_JSON))
    if not path:
        return json.dumps(value).encode()
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    if draw(st.integers(0, 4)):
        parent[path[-1]] = value
    else:
        del parent[path[-1]]
    return json.dumps(doc).encode()


def reads_or_refuses(read, check) -> None:
    """``read()`` must return something that passes ``check`` or raise a one-line InputError naming a file."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with time_limit(CASE_SECONDS):
            try:
                result = read()
            except InputError as err:
                assert "\n" not in str(err) and err.path, str(err)
                return
    check(result)


def quiet(capfd, run) -> None:
    """Run ``run()``; nothing may reach stdout or stderr (libpng, numpy or OpenCV noise)."""
    capfd.readouterr()
    run()
    out, err = capfd.readouterr()
    assert out == "" and err == "", (out, err)


def finite(*arrays) -> None:
    for a in arrays:
        assert np.all(np.isfinite(np.asarray(a, float)))


# ---------------------------------------------------------------------------
# One test per family
# ---------------------------------------------------------------------------

@pytest.mark.slow
@FUZZ
@given(st.data())
def test_fuzz_asf(seeds, capfd, data):
    path = seeds["work"] / "07.asf"
    path.write_bytes(data.draw(mutant(seeds["asf"])))
    amc = seeds["work"] / "07_01.amc"
    amc.write_bytes(seeds["amc"])
    quiet(capfd, lambda: reads_or_refuses(lambda: asf_amc_clip(path, amc), lambda c: finite(c.positions)))


@pytest.mark.slow
@FUZZ
@given(st.data())
def test_fuzz_amc(seeds, capfd, data):
    path = seeds["work"] / "07_02.amc"
    path.write_bytes(data.draw(mutant(seeds["amc"])))
    quiet(capfd, lambda: reads_or_refuses(lambda: asf_amc_clip(SAMPLE_ASF, path), lambda c: finite(c.positions)))


@FUZZ
@given(st.data())
def test_fuzz_bvh(seeds, capfd, data):
    path = seeds["work"] / "fuzz.bvh"
    path.write_bytes(data.draw(mutant(seeds["bvh"])))
    quiet(capfd, lambda: reads_or_refuses(lambda: bvh_clip(path), lambda c: finite(c.positions, c.fps)))


@FUZZ
@given(st.data())
def test_fuzz_cameras_json(seeds, capfd, data):
    path = seeds["work"] / "cameras.json"
    path.write_bytes(data.draw(st.one_of(mutant(seeds["cameras.json"]), json_mutant(seeds["cameras.json"]))))

    def check(rig):
        finite(rig.R, rig.t, rig.focal, rig.principal, rig.dist, rig.project(np.zeros((1, 3)))[1])

    quiet(capfd, lambda: reads_or_refuses(lambda: read_cameras_json(path), check))


@pytest.mark.slow
@FUZZ
@given(st.data())
def test_fuzz_meta_json(seeds, capfd, data):
    (seeds["seq"] / "meta.json").write_bytes(data.draw(st.one_of(mutant(seeds["meta.json"]),
                                                                 json_mutant(seeds["meta.json"]))))

    def check(seq):
        finite(list(seq.model.shape.to_dict()["lengths"].values()), 0.0 if seq.fps is None else seq.fps)

    quiet(capfd, lambda: reads_or_refuses(lambda: read_sequence(seeds["seq"]), check))


@FUZZ
@given(st.data())
def test_fuzz_cal(seeds, capfd, data):
    path = seeds["work"] / "Camera1.cal"
    path.write_bytes(data.draw(mutant(seeds[".cal"])))

    def check(cam):
        finite(cam.R, cam.t, cam.fx, cam.fy, cam.cx, cam.cy, cam.dist)

    quiet(capfd, lambda: reads_or_refuses(lambda: read_bodytrack_calibration(path), check))


@pytest.mark.slow
@FUZZ
@given(st.data())
def test_fuzz_bodytrack_text(seeds, capfd, data):
    bt = seeds["bt"]
    name = data.draw(st.sampled_from(sorted(seeds["bodytrack"])))
    for other, content in seeds["bodytrack"].items():
        (bt / other).write_bytes(content)
    (bt / name).write_bytes(data.draw(mutant(seeds["bodytrack"][name])))
    read = {"BodyShapeParameters.txt": lambda: bodytrack_model(bt)[0],
            "PoseParameters.txt": lambda: read_pose_parameters(bt / name),
            "InitialPose.txt": lambda: read_poses(bt / name)}[name]

    def check(result):
        if isinstance(result, np.ndarray):
            finite(result)
        elif isinstance(result, PoseParameters):
            finite(result.std, result.lower, result.upper)
        else:  # the 10-cone model: its rest pose must be finite
            finite(forward_kinematics(result, np.zeros(result.n_dofs)).points)

    quiet(capfd, lambda: reads_or_refuses(read, check))


@FUZZ
@given(st.data())
def test_fuzz_images(seeds, capfd, data):
    seed = data.draw(st.sampled_from(seeds["images"]))
    path = seeds["work"] / ("000000.png" if seed.startswith(b"\x89PNG") else "image0000.bmp")
    path.write_bytes(data.draw(mutant(seed, text=False)))
    rgb = data.draw(st.booleans())

    def check(img):
        assert img.dtype == np.uint8 and img.shape[:2] == (24, 32) and (img.ndim == 3 or not rgb)

    quiet(capfd, lambda: reads_or_refuses(lambda: read_image(path, 32, 24, rgb=rgb), check))


#: Arrays that may replace one member of the ground truth.
_NASTY_ARRAYS = st.one_of(
    st.sampled_from([np.array("60"), np.array(60.0 + 1j), np.zeros((3, 40), complex), np.array([]),
                     np.zeros((0, 40)), np.zeros((3, 40), bool), np.zeros((3, 40), np.int8), np.array(7),
                     np.full((3, 15, 3), 1e308), np.zeros((3, 15, 3), np.float16), np.array(["a", "b"])]),
    st.builds(lambda shape, value: np.full(shape, value),
              st.sampled_from([(), (1,), (3,), (3, 40), (3, 41), (2, 40), (3, 15, 3), (3, 15, 2), (4, 15, 3)]),
              st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10 ** 6, 10 ** 6))),
)


@FUZZ
@given(st.data())
def test_fuzz_groundtruth_npz(seeds, capfd, data):
    path = seeds["work"] / "groundtruth.npz"
    if data.draw(st.booleans()):
        path.write_bytes(data.draw(mutant(seeds["groundtruth"], text=False)))
    else:
        arrays = {"poses": np.zeros((3, 40)), "markers": np.zeros((3, 15, 3)), "fps": np.float64(60.0)}
        key = data.draw(st.sampled_from(sorted(arrays)))
        if data.draw(st.integers(0, 5)):
            arrays[key] = data.draw(_NASTY_ARRAYS)
        else:
            del arrays[key]
        with open(path, "wb") as f:
            np.savez(f, **arrays)

    def check(gt):
        finite(gt.poses, gt.markers, gt.fps)
        assert gt.poses.shape[0] == gt.markers.shape[0] >= 1 and gt.fps > 0

    quiet(capfd, lambda: reads_or_refuses(lambda: read_groundtruth(path, 40), check))


@pytest.mark.slow
@FUZZ
@given(st.data())
def test_fuzz_converted_clip(seeds, capfd, data):
    """Converted clips: a mutated body-shape JSON, a replaced array, or damaged bytes."""
    path = seeds["work"] / "clip.npz"
    shape = default_shape().to_json().encode()
    arrays = {"poses": np.zeros((3, 40)), "markers": np.zeros((3, 15, 3)), "model_markers": np.zeros((3, 15, 3)),
              "fps": np.float64(60.0), "shape": np.array(data.draw(json_mutant(shape)).decode())}
    if data.draw(st.booleans()):
        arrays[data.draw(st.sampled_from(sorted(arrays)))] = data.draw(_NASTY_ARRAYS)
    with open(path, "wb") as f:
        np.savez(f, **arrays)
    if data.draw(st.integers(0, 3)) == 0:
        path.write_bytes(data.draw(mutant(path.read_bytes(), text=False)))

    def check(clip):
        finite(clip.poses, clip.markers, clip.model_markers, clip.fps)
        finite(forward_kinematics(clip.model, clip.poses).points)

    quiet(capfd, lambda: reads_or_refuses(lambda: load_converted_clip(path), check))


def test_profiles_are_reproducible():
    assert all(p.derandomize and p.database is None for p in PROFILES.values())
