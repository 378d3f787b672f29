"""BVH files from anywhere: the same CMU walk written out in every recognised naming convention (with
namespaces, missing end sites, z up, other units, 30 and 120 Hz) converts to the markers of its ASF/AMC
conversion; other names are mapped with a joint map (JSON or TOML) or refused in one line that lists the
file's joints."""
from __future__ import annotations

import json

import numpy as np
import pytest

from data_tools.motion.asf_amc import asf_amc_clip, read_asf
from data_tools.motion.load import load_mocap, load_training_clips
from data_tools.motion.mocap import MocapClip, marker_positions
from data_tools.motion.retarget import retarget
from tests.bvh_writer import write_bvh
from tests.conftest import SHARED, need_shared
from tracker.app.cli import main
from tracker.core.body import MARKER_NAMES as MARKERS
from tracker.core.errors import InputError

#: Source frames written (1 s of the 120 Hz walk 07_01).
FRAMES = 121
#: How far the converted markers may lie from the ASF/AMC conversion's (mm).
TOLERANCE_MM = 5.0


def sided(table: dict[str, str]) -> dict[str, str]:
    """``{s}`` (l, r), ``{S}`` (L, R) and ``{Side}`` (Left, Right) expanded in keys and values."""
    out = {}
    for k, v in table.items():
        for s, S, side in (("l", "L", "Left"), ("r", "R", "Right")):
            out[k.replace("{s}", s)] = v.replace("{s}", s).replace("{S}", S).replace("{Side}", side)
    return out


MOTIONBUILDER = sided({
    "lowerback": "Spine", "upperback": "Spine1", "thorax": "Spine2", "lowerneck": "Neck", "upperneck": "Neck1",
    "head": "Head", "{s}hipjoint": "{S}HipJoint", "{s}femur": "{Side}UpLeg", "{s}tibia": "{Side}Leg",
    "{s}foot": "{Side}Foot", "{s}toes": "{Side}ToeBase", "{s}clavicle": "{Side}Shoulder", "{s}humerus": "{Side}Arm",
    "{s}radius": "{Side}ForeArm", "{s}wrist": "{Side}Hand", "{s}fingers": "{Side}HandMiddle1",
    "{s}thumb": "{Side}HandThumb1",
})
LAFAN1 = {**MOTIONBUILDER, "ltoes": "LeftToe", "rtoes": "RightToe"}
BIOVISION = sided({
    "lowerback": "Chest", "upperback": "Chest2", "thorax": "Chest3", "lowerneck": "Neck", "upperneck": "Neck2",
    "head": "Head", "{s}femur": "{Side}Hip", "{s}tibia": "{Side}Knee", "{s}foot": "{Side}Ankle",
    "{s}clavicle": "{Side}Collar", "{s}humerus": "{Side}Shoulder", "{s}radius": "{Side}Elbow",
    "{s}wrist": "{Side}Wrist",
})
POSER = sided({
    "lowerback": "abdomen", "upperback": "chest", "lowerneck": "neck", "head": "head", "{s}hipjoint": "{s}Buttock",
    "{s}femur": "{s}Thigh", "{s}tibia": "{s}Shin", "{s}foot": "{s}Foot", "{s}clavicle": "{s}Collar",
    "{s}humerus": "{s}Shldr", "{s}radius": "{s}ForeArm", "{s}wrist": "{s}Hand", "{s}fingers": "{s}Mid1",
    "{s}thumb": "{s}Thumb1",
})
HANDS = ("lhand", "rhand", "lthumb", "rthumb")
TOES = ("ltoes", "rtoes")

#: name -> (writer settings, what the summary says: naming, unit, up axis, rate).
VARIANTS = {
    "ASF bone names, 120 Hz": (dict(names="asf", root="root"), ("ASF bone names", "cm", "y up", "120 Hz")),
    "Mixamo, 30 Hz": (dict(names=MOTIONBUILDER, prefix="mixamorig:", every=4,
                           end_joints={"head": "HeadTop_End", "ltoes": "LeftToe_End", "rtoes": "RightToe_End"}),
                      ("MotionBuilder", "namespace mixamorig: ignored", "cm", "y up", "30 Hz")),
    "LAFAN1, 30 Hz": (dict(names=LAFAN1, every=4, drop=HANDS), ("MotionBuilder", "cm", "y up", "30 Hz")),
    "SFU-style, z up, metres, 120 Hz": (dict(names=MOTIONBUILDER, z_up=True, mm_per_unit=1000.0),
                                        ("MotionBuilder", "lengths in m", "z up", "120 Hz")),
    "MocapBank, no hand or toe ends, inches, 30 Hz": (
        dict(names=BIOVISION, every=4, drop=HANDS + TOES, bare=("lfoot", "rfoot", "lwrist", "rwrist"),
             mm_per_unit=25.4), ("Biovision (MocapBank)", "inch", "y up", "30 Hz")),
    "Poser, 120 Hz": (dict(names=POSER, root="hip", drop=TOES), ("Poser (DAZ)", "cm", "y up", "120 Hz")),
}


@pytest.fixture(scope="module")
def walk(mocap_dir):
    """The ASF, the AMC, and the first :data:`FRAMES` frames of their conversion."""
    asf, amc = mocap_dir / "07" / "07.asf", mocap_dir / "07" / "07_01.amc"
    clip = asf_amc_clip(asf, amc)
    cut = MocapClip(clip.path, clip.positions[:FRAMES], clip.point_names, clip.fps, clip.style, unit=clip.unit)
    return asf, amc, cut


@pytest.fixture(scope="module")
def reference(walk):
    """The ASF/AMC conversion at a rate, computed once per rate."""
    cache = {}

    def at(fps: float):
        if fps not in cache:
            cache[fps] = retarget(walk[2], fps)
        return cache[fps]
    return at


def write(walk, path, settings: dict):
    asf, amc, _ = walk
    settings = dict(settings)
    if settings.get("names") == "asf":
        settings["names"] = {b: b for b in read_asf(asf).bones}
    return write_bvh(path, asf, amc, frames=FRAMES, **settings)


def gap_mm(a, b) -> float:
    """The largest distance (mm) between two marker arrays ``T x 15 x 3``."""
    assert a.shape == b.shape, (a.shape, b.shape)
    return float(np.linalg.norm(a - b, axis=-1).max())


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_every_convention_converts_to_the_asf_markers(walk, reference, tmp_path, variant):
    settings, summary = VARIANTS[variant]
    clip = load_mocap(write(walk, tmp_path / "walk.bvh", settings))
    for fragment in summary:
        assert fragment in clip.summary(), (fragment, clip.summary())
    result = retarget(clip)  # at the file's own rate
    ref = reference(clip.fps)
    assert result.fps == clip.fps and len(result.poses) == len(ref.poses)
    assert gap_mm(result.markers, ref.markers) < TOLERANCE_MM
    # The fitted model agrees too (derived hand ends and toes move only hands and feet).
    assert np.linalg.norm(result.model_markers - ref.model_markers, axis=-1).mean() < TOLERANCE_MM


def test_missing_ends_are_derived_and_said(walk, tmp_path):
    settings, _ = VARIANTS["MocapBank, no hand or toe ends, inches, 30 Hz"]
    clip = load_mocap(write(walk, tmp_path / "walk.bvh", settings))
    notes = " ".join(clip.notes)
    for point in ("left_hand_end", "right_hand_end", "left_toe", "right_toe"):
        assert f"{point} derived from" in notes
    assert "forward axis" in notes and "forearm" in notes
    # Derived from a standing skeleton's proportions, they lie near the walk's own hand ends and toes: the
    # hands continue the forearm (about 23 mm off), the toes follow the pelvis, not the ankle's flexion
    # (about 50 mm off).
    true, derived = marker_positions(walk[2])[::4, 15:], marker_positions(clip)[:, 15:]
    off = np.linalg.norm(true - derived, axis=-1).mean(axis=0)
    assert np.all(off[:2] < 35) and np.all(off[2:] < 75), off


@pytest.mark.parametrize("written_every, fps", [(1, 60.0), (1, 50.0), (4, 60.0), (4, 120.0)])
def test_any_rate_is_interpolated_like_the_time_warp(walk, reference, tmp_path, written_every, fps):
    """120 Hz down to 60 reads every second frame; 50 Hz and a 30 Hz file up to 60 or 120 interpolate. Where
    the samples fall on the file's frames the markers are the ASF conversion's; between 30 Hz frames they are
    interpolated, within the tolerance of the walk's true positions."""
    clip = load_mocap(write(walk, tmp_path / "walk.bvh", dict(names=MOTIONBUILDER, every=written_every)))
    result, ref = retarget(clip, fps), reference(fps)
    assert result.fps == fps and len(result.poses) == len(ref.poses)
    step = clip.fps / fps
    on_frames = np.flatnonzero(np.abs(np.arange(len(ref.poses)) * step % 1) < 1e-9)
    assert gap_mm(result.markers[on_frames], ref.markers[on_frames]) < 1e-2
    assert np.linalg.norm(result.markers - ref.markers, axis=-1).mean() < TOLERANCE_MM
    assert np.abs(np.diff(result.poses[:, 3:6], axis=0)).max() < 0.2  # continuous root rotation


def test_thirty_hertz_file_converts_at_default_settings(walk, tmp_path, capsys):
    settings, _ = VARIANTS["Mixamo, 30 Hz"]
    bvh = write(walk, tmp_path / "mixamo.bvh", settings)
    out = tmp_path / "clip.npz"
    capsys.readouterr()
    assert main(["convert", "--mocap", str(bvh), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    lines = [line for line in (captured.out + captured.err).splitlines() if line.startswith("mixamo.bvh: ")]
    assert len(lines) == 1, captured  # one summary line
    line = lines[0]
    assert line.startswith("mixamo.bvh: MotionBuilder (Mixamo, LAFAN1, SFU) names (namespace mixamorig: ignored), "
                           "lengths in cm")
    assert "y up, 30 Hz; 31 frames at 30 fps" in line
    with np.load(out) as d:
        assert float(d["fps"]) == 30.0 and d["markers"].shape == (31, 15, 3)


def foreign_names(walk, tmp_path):
    """The walk with joint names no convention knows (``J_<bone>``) and a joint map for it."""
    asf = walk[0]
    bvh = write(walk, tmp_path / "foreign.bvh", dict(names={b: f"J_{b}" for b in read_asf(asf).bones},
                                                      root="J_root", every=4))
    mapping = {"pelvis": "J_root", "thorax": "J_lowerneck", "head": "J_head_end"}
    for side, s in (("left", "l"), ("right", "r")):
        mapping.update({f"{side}_shoulder": f"J_{s}humerus", f"{side}_elbow": f"J_{s}radius",
                        f"{side}_wrist": f"J_{s}wrist", f"{side}_hip": f"J_{s}femur", f"{side}_knee": f"J_{s}tibia",
                        f"{side}_ankle": f"J_{s}foot", f"{side}_toe": f"J_{s}toes"})
    return bvh, mapping


def test_unrecognised_names_are_refused_listing_the_joints(walk, tmp_path, capsys):
    bvh, _ = foreign_names(walk, tmp_path)
    capsys.readouterr()
    code = main(["convert", "--mocap", str(bvh), "--out", str(tmp_path / "c.npz")])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1, err
    for fragment in ("foreign.bvh", "joint names not recognised", "J_root, J_lhipjoint, J_lfemur", "--joint-map",
                     "docs/guide/motion_capture.md"):
        assert fragment in err[0], (fragment, err[0])
    assert not (tmp_path / "c.npz").exists()


def toml_text(mapping: dict) -> str:
    return "".join(f'{k} = "{v}"\n' for k, v in mapping.items())


@pytest.mark.parametrize("kind", ["json", "toml"])
def test_joint_map_names_the_points(walk, reference, tmp_path, capsys, kind):
    bvh, mapping = foreign_names(walk, tmp_path)
    joint_map = tmp_path / f"map.{kind}"
    joint_map.write_text(json.dumps(mapping) if kind == "json" else "# our points = the file's joints\n"
                         + toml_text(mapping))
    out = tmp_path / "clip.npz"
    capsys.readouterr()
    assert main(["convert", "--mocap", str(bvh), "--joint-map", str(joint_map), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert f"joints from the joint map map.{kind}" in captured.out + captured.err
    assert "left_hand_end derived from the left wrist and forearm" in captured.out + captured.err
    with np.load(out) as d:
        assert gap_mm(d["markers"], reference(30.0).markers) < TOLERANCE_MM


@pytest.mark.parametrize("content, fragments", [
    ('pelvis = "J_root"\nelbow = "J_lradius"\n', ("unknown point(s) 'elbow'", "left_elbow")),
    ('pelvis = "J_nowhere"\n', ("names 'J_nowhere' for pelvis, which the file lacks", "J_root")),
    ('pelvis = "J_root"\n', ("gives no joint for thorax, head, left_shoulder",)),
    ('pelvis = \n', ("not valid TOML",)),
    ('pelvis = 3\n', ("pelvis must be a joint name or a list of joint names",)),
])
def test_bad_joint_maps_are_refused_in_one_line(walk, tmp_path, capsys, content, fragments):
    bvh, _ = foreign_names(walk, tmp_path)
    joint_map = tmp_path / "map.toml"
    joint_map.write_text(content)
    capsys.readouterr()
    code = main(["convert", "--mocap", str(bvh), "--joint-map", str(joint_map), "--out", str(tmp_path / "c.npz")])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1 and "Traceback" not in err[0], err
    for fragment in fragments:
        assert fragment in err[0], (fragment, err[0])


def test_api_and_training_take_joint_maps(walk, reference, tmp_path):
    import tracker

    bvh, mapping = foreign_names(walk, tmp_path)
    clip = tracker.load_clip(bvh, fps=None, joint_map=mapping)
    assert clip.fps == 30.0 and gap_mm(clip.markers, reference(30.0).markers) < TOLERANCE_MM
    mixamo = write(walk, tmp_path / "mixamo.bvh", VARIANTS["Mixamo, 30 Hz"][0])
    clips = load_training_clips([bvh, mixamo], None, 60.0, [mapping, "none"])
    assert [c.fps for c in clips] == [60.0, 60.0] and len(clips[0].poses) == len(clips[1].poses) == 61
    with pytest.raises(InputError, match="one joint map for all clips or one per clip"):
        load_training_clips([bvh, mixamo], None, 60.0, [mapping, "none", "none"])
    model = tracker.train("crbm", [bvh, mixamo], joint_maps=[mapping, None], order=1, hidden=4, epochs=1, seed=0)
    assert model.fps == 60.0


def test_experiment_sequences_take_joint_maps(walk, tmp_path):
    from tracker.app.experiment import load_experiment

    bvh, mapping = foreign_names(walk, tmp_path)
    (tmp_path / "map.toml").write_text(toml_text(mapping))
    text = (f'[[sequence]]\nname = "walk"\nmocap = "{bvh}"\njoint_map = "map.toml"\nframes = 6\n\n'
            '[[prior]]\nname = "zero-velocity"\n')
    path = tmp_path / "exp.toml"
    path.write_text(text)
    assert load_experiment(path).sequences[0].synth["joint_map"] == mapping  # its content: part of the cache key
    path.write_text(text.replace('joint_map = "map.toml"', 'then_joint_map = "map.toml"'))
    with pytest.raises(InputError, match="then_joint_map applies to a transition"):
        load_experiment(path)


def test_experiment_training_clips_take_joint_maps(walk, reference, tmp_path):
    from tracker.app.clips import load_clip_specs
    from tracker.app.experiment import load_experiment

    bvh, mapping = foreign_names(walk, tmp_path)
    (tmp_path / "map.toml").write_text(toml_text(mapping))
    seq = write(walk, tmp_path / "mixamo.bvh", VARIANTS["Mixamo, 30 Hz"][0])
    path = tmp_path / "exp.toml"
    path.write_text(f'[[sequence]]\nname = "walk"\nmocap = "{seq}"\nframes = 6\n\n'
                    f'[[prior]]\nname = "crbm"\ntrain = [{{ mocap = [{{ path = "{bvh}", joint_map = "map.toml" }}, '
                    f'"{seq}"], options = {{ order = 1 }} }}]\n')
    clips = load_experiment(path).priors[0].train[0].mocap
    assert clips[0].joint_map == mapping and clips[1].joint_map is None  # its content: part of the model's key
    loaded = load_clip_specs(clips, 30.0)
    assert gap_mm(loaded[0].markers, reference(30.0).markers) < TOLERANCE_MM and len(loaded[1].poses) > 3


# Files from game and animation pipelines: joint orients baked into the offsets (with every rotation zero the
# skeleton lies along x), six channels on every joint, an extra root on the ground above the hips, End Sites
# at their joints, `_L`/`_R` names. Written from the packaged sample walk: no shared data needed.

GAME_RIG = sided({
    "lowerback": "Spine", "upperback": "Chest", "lowerneck": "Neck", "head": "Head",
    "{s}clavicle": "Shoulder_{S}", "{s}humerus": "UpperArm_{S}", "{s}radius": "LowerArm_{S}", "{s}wrist": "Hand_{S}",
    "{s}femur": "UpperLeg_{S}", "{s}tibia": "LowerLeg_{S}", "{s}foot": "Foot_{S}", "{s}toes": "Toes_{S}",
})
RIG = dict(names=GAME_RIG, orients=True, positions=True, extra_root="joint_Root", zero_ends=True, drop=HANDS)
#: How far the derived head end may lie from the walk's own (mm): it is placed by the torso's length
#: (``HEAD_PER_TORSO``, a median over several skeletons) on the neck's line; subject 7's head ends 40 mm
#: nearer the thorax than that, and up to 55 mm from it with the head's own nod.
HEAD_TOLERANCE_MM = 60.0


@pytest.fixture(scope="module")
def sample_walk():
    """The packaged CMU walk's ASF, AMC, its first :data:`FRAMES` frames' conversion, and their markers
    retargeted at a rate (computed once per rate)."""
    from data_tools.samples import sample_walks

    asf, amcs = sample_walks()
    clip = asf_amc_clip(asf, amcs[0])
    cut = MocapClip(clip.path, clip.positions[:FRAMES], clip.point_names, clip.fps, clip.style, unit=clip.unit)
    cache = {}

    def at(fps: float):
        if fps not in cache:
            cache[fps] = retarget(cut, fps)
        return cache[fps]
    return asf, amcs[0], cut, at


@pytest.mark.parametrize("settings, summary", [
    (dict(RIG, every=4), ("Bandai Namco", "lengths in cm", "y up", "30 Hz")),
    (dict(RIG, z_up=True, mm_per_unit=1000.0), ("Bandai Namco", "lengths in m", "z up", "120 Hz")),
    (dict(RIG, mm_per_unit=25.4, every=2), ("Bandai Namco", "lengths in inch", "y up", "60 Hz")),
], ids=["cm y-up 30 Hz", "m z-up 120 Hz", "inch y-up 60 Hz"])
def test_game_rig_converts_with_no_flags(sample_walk, tmp_path, settings, summary):
    """The rest skeleton lies down, so the up axis and the unit come from the posed frames; the extra root is
    not the pelvis; the markers are the ASF conversion's, but for the derived head end."""
    asf, amc, _, reference = sample_walk
    path = write_bvh(tmp_path / "rig.bvh", asf, amc, frames=FRAMES, **settings)
    assert "ROOT joint_Root" in path.read_text()
    clip = load_mocap(path)
    for fragment in summary:
        assert fragment in clip.summary(), (fragment, clip.summary())
    notes = " ".join(clip.notes)
    for fragment in ("does not stand: up axis and length unit read from the frames", "head derived",
                     "left_hand_end derived"):
        assert fragment in notes, (fragment, notes)
    result, ref = retarget(clip), reference(clip.fps)
    assert len(result.markers) == len(ref.markers)
    head = MARKERS.index("head")
    others = [i for i in range(len(MARKERS)) if i != head]
    assert gap_mm(result.markers[:, others], ref.markers[:, others]) < TOLERANCE_MM
    assert np.linalg.norm(result.markers[:, head] - ref.markers[:, head], axis=-1).max() < HEAD_TOLERANCE_MM
    assert result.mean_residual < 2.0


def test_game_rig_convert_says_how_it_read_the_file(sample_walk, tmp_path, capsys):
    asf, amc, _, _ = sample_walk
    path = write_bvh(tmp_path / "rig.bvh", asf, amc, frames=FRAMES, every=4, **RIG)
    capsys.readouterr()
    assert main(["convert", "--mocap", str(path), "--out", str(tmp_path / "rig.npz")]) == 0
    captured = capsys.readouterr()
    lines = [line for line in (captured.out + captured.err).splitlines() if "rig.bvh" in line]
    summary = [line for line in lines if line.startswith("rig.bvh: ")]
    assert len(summary) == 1 and summary[0].startswith(
        "rig.bvh: Bandai Namco (UpperArm_L, game rig) names, lengths in cm (inferred from the skeleton's height), "
        "y up, 30 Hz; 31 frames at 30 fps"), lines
    assert any(line.startswith("note: rig.bvh: the rest skeleton (every rotation zero) does not stand")
               for line in lines), lines


def test_position_channels_on_every_joint_keep_a_standing_rest(sample_walk, tmp_path):
    """Six channels on every joint of an upright skeleton: read as before, from the rest skeleton, no note."""
    asf, amc, _, reference = sample_walk
    clip = load_mocap(write_bvh(tmp_path / "six.bvh", asf, amc, frames=FRAMES, names=MOTIONBUILDER, positions=True,
                                every=4))
    assert "MotionBuilder" in clip.summary() and "lengths in cm" in clip.summary() and "y up" in clip.summary()
    assert not any("does not stand" in n for n in clip.notes)
    assert gap_mm(retarget(clip).markers, reference(30.0).markers) < TOLERANCE_MM


def test_a_skeleton_lying_in_its_frames_too_is_refused_in_one_line(sample_walk, tmp_path, capsys):
    asf, amc, _, _ = sample_walk
    path = write_bvh(tmp_path / "lying.bvh", asf, amc, frames=8, **RIG)
    lines = path.read_text().splitlines()
    motion = lines.index("MOTION") + 3
    for k in range(motion, len(lines)):  # every rotation zero: the frames are the rest skeleton
        values = np.array(lines[k].split(), float).reshape(-1, 6)
        values[:, 3:] = 0.0
        lines[k] = " ".join(f"{v:.6f}" for v in values.ravel())
    path.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    code = main(["convert", "--mocap", str(path), "--out", str(tmp_path / "c.npz")])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1, err
    assert "lying.bvh" in err[0] and "the skeleton in its frames stands along" in err[0] and "x" in err[0], err


#: Real clips of that convention (Bandai Namco Research's motion dataset 2, CC BY-NC 4.0): content, style ->
#: the range of walking speed (m/s) they must show. Lengths in cm, y up, 30 Hz; one skeleton about 1.6 m tall.
BANDAI_CLIPS = {("walk", "normal"): (0.9, 1.4), ("run", "normal"): (2.0, 4.5),
                ("walk-turn-left", "active"): (0.8, 1.6), ("wave-right-hand", "elderly"): (0.0, 0.1)}


@pytest.mark.shared
@pytest.mark.parametrize("content, style", sorted(BANDAI_CLIPS))
def test_bandai2_clips_convert_with_no_flags(content, style):
    folder = need_shared(SHARED / "mocap" / "bandai2")
    clip = load_mocap(folder / f"dataset-2_{content}_{style}_001.bvh")
    assert clip.summary() == ("Bandai Namco (UpperArm_L, game rig) names, lengths in cm (inferred from the "
                              "skeleton's height), y up, 30 Hz")
    points = marker_positions(clip)
    # Height: the head end above the lowest point of the skeleton, median over frames.
    height = np.median(points[:, MARKERS.index("head"), 2] - clip.positions[..., 2].min(axis=1))
    assert 1500 < height < 1750, height
    # Speed: the pelvis's path over the ground, smoothed over a second (its sway averaged out).
    k = int(clip.fps)
    pelvis = np.stack([np.convolve(points[:, 0, i], np.ones(k) / k, mode="valid") for i in range(2)], axis=1)
    speed = np.linalg.norm(np.diff(pelvis, axis=0), axis=1).sum() / 1000 / ((len(pelvis) - 1) / clip.fps)
    low, high = BANDAI_CLIPS[content, style]
    assert low <= speed <= high, speed
    assert retarget(clip, fps=5.0).mean_residual < 3.0
