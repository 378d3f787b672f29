"""Shared fixtures. Tests that need ../shared skip with a reason when it is absent (CI always has it)."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("TRACKER_SHARED", REPO.parent / "shared"))
MOCAP = SHARED / "mocap" / "cmu"
BODYTRACK = SHARED / "bodytrack" / "sequenceB_1"
#: Tests convert clips afresh and never write to the user's cache of converted clips (data_tools.motion.cache); the
#: cache's own tests name their folder.
os.environ["POSE_TRACKER_CACHE"] = "off"

#: Frame counts of every shared clip (README of ../shared/mocap; BVH headers).
SHARED_CLIPS = {
    "07/07_01.amc": 316, "07/07_02.amc": 329, "07/07_09.amc": 306, "07/07_10.amc": 301, "07/07_11.amc": 315,
    "49/49_18.amc": 1102, "49/49_19.amc": 957, "49/49_20.amc": 898,
    "bvh/10_01.bvh": 802, "bvh/10_03.bvh": 363, "bvh/11_01.bvh": 598, "bvh/131_01.bvh": 994,
}


def need_shared(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"shared data not found at {path} (set TRACKER_SHARED or place ../shared beside the repo)")
    return path


#: Fixtures that read ../shared. A test whose fixtures include one of them, or a fixture built on one (pytest's
#: ``fixturenames`` is the whole closure), is marked ``shared``; a test that calls ``need_shared`` itself carries
#: the mark beside it.
SHARED_FIXTURES = frozenset({"mocap_dir", "bodytrack_dir"})


#: The example plugin registers its prior, likelihood and reader when its test module is imported (at collection)
#: and takes them out after that module's tests; run first, as it did when every test module lay in tests/, it
#: leaves the registries as the package fills them for every other test.
PLUGIN_EXAMPLE = Path(__file__).resolve().parent / "plugin_example"


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: PLUGIN_EXAMPLE not in Path(item.path).resolve().parents)
    for item in items:
        if SHARED_FIXTURES.intersection(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.shared)


@pytest.fixture(scope="session")
def mocap_dir() -> Path:
    return need_shared(MOCAP)


@pytest.fixture(scope="session")
def bodytrack_dir() -> Path:
    return need_shared(BODYTRACK)


@pytest.fixture(scope="session")
def walk_07_01(mocap_dir):
    """07_01 retargeted at 60 Hz (the realistic clip most tests use)."""
    from data_tools.motion.asf_amc import asf_amc_clip
    from data_tools.motion.retarget import retarget

    return retarget(asf_amc_clip(mocap_dir / "07" / "07.asf", mocap_dir / "07" / "07_01.amc"), fps=60)


@pytest.fixture
def no_mediapipe(monkeypatch) -> None:
    """MediaPipe made unimportable, as if not installed, its modules an earlier test imported included."""
    import sys

    for name in [n for n in sys.modules if n.split(".")[0] == "mediapipe"] + ["mediapipe"]:
        monkeypatch.setitem(sys.modules, name, None)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def walk_07_11(mocap_dir):
    """07_11 (the held-out walk) retargeted at 60 Hz: the clip synthetic-sequence tests render."""
    from data_tools.motion.asf_amc import asf_amc_clip
    from data_tools.motion.retarget import retarget

    return retarget(asf_amc_clip(mocap_dir / "07" / "07.asf", mocap_dir / "07" / "07_11.amc"), fps=60)


@pytest.fixture(scope="session")
def synthetic_walk(walk_07_11, tmp_path_factory):
    """A 6-frame, 4-view synthetic sequence of 07_11 at the default noise, with the renderer's exact masks."""
    from data_tools.synthesis.synth import SynthConfig, synthesize

    out = synthesize(walk_07_11, tmp_path_factory.mktemp("seq") / "walk", SynthConfig(start=40, frames=6),
                     source="07_11.amc", keep_masks=True)
    return out


@pytest.fixture(scope="session")
def random_walk_std(mocap_dir):
    """Zero-velocity scale from the training walks 07_01 and 07_02 at 60 Hz (rms frame-to-frame change)."""
    from data_tools.motion.asf_amc import asf_amc_clip
    from data_tools.motion.retarget import retarget
    from tracker.core.representation import step_rms

    asf = mocap_dir / "07" / "07.asf"
    return step_rms([retarget(asf_amc_clip(asf, mocap_dir / "07" / f"07_{i}.amc"), fps=60).poses
                     for i in ("01", "02")])


@pytest.fixture(scope="session")
def walk_32_frames(walk_07_11, tmp_path_factory):
    """The first 32 frames of the held-out walk 07_11 rendered into 4 views (default noise, seed 0)."""
    from data_tools.sequences.sequence import read_sequence
    from data_tools.synthesis.synth import SynthConfig, synthesize

    out = synthesize(walk_07_11, tmp_path_factory.mktemp("seq32") / "walk", SynthConfig(frames=32))
    return read_sequence(out.root)


@pytest.fixture(scope="session")
def small_walk(tmp_path_factory) -> Path:
    """Five frames of the shipped walk 07_02 in two small cameras (no ../shared needed): a sequence folder."""
    import tracker

    sample = REPO / "data_tools" / "samples" / "cmu07"
    out = tmp_path_factory.mktemp("small_walk") / "walk"
    tracker.synthesize(sample / "07_02.amc", out, skeleton=sample / "07.asf", cameras=2, frames=5, width=160,
                       height=120)
    return out


#: Frames of the rendered walk that the video round trips import.
ROUND_TRIP_FRAMES = 8


@pytest.fixture(scope="session")
def rendered_walk(mocap_dir, tmp_path_factory):
    """The held-out walk 07_11 at 15 Hz (so that in a few frames the walker leaves every pixel of the start,
    as a background learnt from the frames needs), 8 frames in four 480 x 360 views, written as one MPEG-4
    video per camera; returns the folder, the rendered sequence and the videos."""
    import cv2

    from data_tools.motion.asf_amc import asf_amc_clip
    from data_tools.motion.retarget import retarget
    from data_tools.sequences.sequence import read_sequence
    from data_tools.synthesis.synth import SynthConfig, synthesize

    walk = retarget(asf_amc_clip(mocap_dir / "07" / "07.asf", mocap_dir / "07" / "07_11.amc"), fps=15)
    folder = tmp_path_factory.mktemp("round_trip")
    synthesize(walk, folder / "rendered", SynthConfig(views=4, frames=ROUND_TRIP_FRAMES, width=480, height=360, seed=1))
    rendered = read_sequence(folder / "rendered")
    videos = []
    for v, cam in enumerate(rendered.rig.cameras):
        path = folder / f"{cam.name}.mp4"
        out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), rendered.fps, (cam.width, cam.height))
        for k in range(rendered.n_frames):
            out.write(cv2.cvtColor(rendered.image(k, v), cv2.COLOR_RGB2BGR))
        out.release()
        videos.append(path)
    return folder, rendered, videos
