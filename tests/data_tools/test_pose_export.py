"""Poses out: BVH that reads back to the model's joints, TRC written and read in the same world, and the
comparison with a reference reconstruction after one rigid alignment."""
from __future__ import annotations

import json

import numpy as np
import pytest

from data_tools.motion.bvh import _positions, read_bvh
from data_tools.motion.bvh_export import TO_Y_UP, write_bvh
from data_tools.motion.trc import read_trc, write_trc
from data_tools.sequences.reference import POSE2SIM_MAP, compare_to_reference, rigid_alignment
from data_tools.sequences.sequence import write_image, write_sequence_header
from tests.conftest import SHARED, need_shared
from tracker.app.cli import main
from tracker.core.body import MARKER_NAMES, fifteen_cone_model
from tracker.core.cameras import CameraRig, look_at
from tracker.core.errors import InputError
from tracker.core.kinematics import forward_kinematics, markers
from tracker.core.rotations import exp_map_to_matrix

EXAMPLE = SHARED / "realvideo" / "pose2sim_static"


def random_poses(n: int, seed: int = 0) -> np.ndarray:
    model = fifteen_cone_model()
    rng = np.random.default_rng(seed)
    poses = np.tile(model.rest_pose(), (n, 1))
    poses[:, :3] += rng.normal(0, 300, (n, 3))
    poses[:, 3:] += rng.uniform(-0.6, 0.6, (n, model.n_dofs - 3))
    return np.clip(poses, model.lower, model.upper)


@pytest.mark.parametrize("unit, scale", [("m", 1000.0), ("cm", 10.0)])
def test_bvh_reads_back_to_the_models_joints(tmp_path, unit, scale):
    model = fifteen_cone_model()
    poses = random_poses(4)
    write_bvh(tmp_path / "run.bvh", model, poses, 60.0, unit=unit)
    bvh = read_bvh(tmp_path / "run.bvh")
    assert bvh.frame_time == pytest.approx(1 / 60) and len(bvh.frames) == 4
    points, names = _positions(bvh, bvh.frames)
    fk = forward_kinematics(model, poses)
    link_names = [link.name for link in model.links]
    joints = points[:, :len(link_names)] * scale @ TO_Y_UP  # back to our z-up world, mm
    assert np.abs(joints - fk.origins[:, [link_names.index(n) for n in names[:len(link_names)]]]).max() < 0.01
    head_end = points[:, names.index("head_end")] * scale @ TO_Y_UP
    assert np.abs(head_end - fk.points[:, [p.name for p in model.points].index("head")]).max() < 0.01
    rest_height = read_bvh(tmp_path / "run.bvh").joints[2].end_offset  # the head's end site: y up
    assert rest_height[1] > 0 and rest_height[0] == rest_height[2] == 0


def test_trc_round_trip_keeps_our_world_and_units(tmp_path):
    model = fifteen_cone_model()
    pts = markers(model, random_poses(3))
    pts[1, 4] = np.nan  # a missing value stays missing
    write_trc(tmp_path / "m.trc", MARKER_NAMES, pts, 50.0)
    back = read_trc(tmp_path / "m.trc")
    assert back.names == list(MARKER_NAMES) and back.fps == 50.0 and list(back.frame_numbers) == [1, 2, 3]
    assert np.isnan(back.points[1, 4]).all()
    ok = np.isfinite(pts)
    assert np.abs(back.points[ok] - pts[ok]).max() < 1e-3 + 1e-9  # mm (micrometre rounding)
    lines = (tmp_path / "m.trc").read_text().splitlines()
    head = [float(v) for v in lines[5].split("\t")[2 + 3 * 2:2 + 3 * 3]]  # TRC is y up, metres
    assert head[1] == pytest.approx(pts[0, 2, 2] / 1000, abs=1e-6)


def test_bad_trc_files_are_one_line(tmp_path):
    for text, problem in (("x\n", "5 header lines"),
                          ("P\nDataRate\tNumMarkers\tUnits\n60\t1\tfurlong\nF\tT\ta\n\n1\t0\t1\t2\t3\n", "Units"),
                          ("P\nDataRate\tNumMarkers\tUnits\n60\t2\tm\nF\tT\ta\n\n1\t0\t1\t2\t3\n", "names 1"),
                          ("P\nDataRate\tNumMarkers\tUnits\n60\t1\tm\nF\tT\ta\n\n1\t0\tx\t2\t3\n", "numbers")):
        path = tmp_path / "bad.trc"
        path.write_text(text)
        with pytest.raises(InputError, match=problem) as err:
            read_trc(path)
        assert str(path) in str(err.value)


def test_comparison_undoes_one_rigid_motion_and_reports_per_joint():
    model = fifteen_cone_model()
    est = markers(model, random_poses(5, seed=1))
    R, t = exp_map_to_matrix(np.array([0.1, -0.3, 1.2])), np.array([900.0, -400.0, 20.0])
    names = ["RHip", "LHip", "Neck", "Head", "LShoulder", "LElbow", "LWrist", "RShoulder", "RElbow", "RWrist",
             "LKnee", "LAnkle", "RKnee", "RAnkle"]
    index = {m: i for i, m in enumerate(MARKER_NAMES)}
    ref = np.stack([est[:, index[{"RHip": "right_hip", "LHip": "left_hip", "Neck": "thorax", "Head": "head"}.get(
        n, "_".join(("left" if n[0] == "L" else "right", n[1:].lower())))]] for n in names], axis=1) @ R.T + t
    ref[:, names.index("LWrist")] += [0.0, 0.0, 30.0]  # a keypoint defined 30 mm off our marker
    result = compare_to_reference(est, names, ref)
    assert set(result.per_joint) == set(MARKER_NAMES) - {"pelvis"}
    assert result.per_joint["left_wrist"] == pytest.approx(30.0, abs=5.0)  # the offset spreads a little
    assert result.per_joint["head"] < 5.0 and result.frames == 5
    assert "mean" in result.table()
    shifted = compare_to_reference(est[1:], names, ref, offset=1)
    assert shifted.frames == 4 and shifted.per_joint["head"] < 5.0
    R2, t2 = rigid_alignment(est[0], est[0] @ R.T + t)
    assert np.allclose(R2, R) and np.allclose(t2, t)


@pytest.mark.shared
def test_example_reference_reads_in_the_calibrations_world():
    ref = read_trc(need_shared(EXAMPLE / "static_0-12.trc"))
    assert len(ref.points) == 12 and len(ref.names) == 21 and ref.fps == 60.0
    head = ref.points[0, ref.names.index("Head")]
    ankle = ref.points[0, ref.names.index("RAnkle")]
    assert 1600 < head[2] < 1800 and 50 < ankle[2] < 200  # z up, mm
    assert all(all(s in ref.names for s in sources) for sources in POSE2SIM_MAP.values())


def test_export_and_compare_commands(tmp_path, capsys):
    model = fifteen_cone_model()
    seq = tmp_path / "seq"
    cams = CameraRig([look_at("c0", (3000.0, 0.0, 1000.0), (0.0, 0.0, 900.0), 32, 24, 30.0)])
    write_sequence_header(seq, cams, {"fps": 30.0, "first_video_frame": 1})
    write_image(seq / "images" / "c0" / "000000.png", np.zeros((24, 32, 3), np.uint8))
    write_image(seq / "images" / "c0" / "000001.png", np.zeros((24, 32, 3), np.uint8))
    poses = random_poses(2)
    run = tmp_path / "run"
    run.mkdir()
    np.savez(run / "estimates.npz", poses=poses, markers=markers(model, poses), best_poses=poses)
    (run / "result.json").write_text(json.dumps({"sequence": str(seq)}))
    assert main(["export", str(run), "--bvh", str(tmp_path / "a.bvh"), "--trc", str(tmp_path / "a.trc")]) == 0
    assert "30 Hz" in capsys.readouterr().out
    trc = read_trc(tmp_path / "a.trc")
    assert np.abs(trc.points - markers(model, poses)).max() < 1e-3
    assert read_bvh(tmp_path / "a.bvh").frames.shape[0] == 2
    # The TRC as a reference whose first frame is a frame before the run: the offset read from meta.json
    padded = np.concatenate([trc.points[:1] + 500.0, trc.points])
    write_trc(tmp_path / "ref.trc", ["LHip", "Head", "LKnee", "RKnee"],  # one hip: no pelvis is mapped
              padded[:, [MARKER_NAMES.index(n) for n in ("left_hip", "head", "left_knee", "right_knee")]], 30.0)
    assert main(["compare-trc", str(run), str(tmp_path / "ref.trc")]) == 0
    out = capsys.readouterr().out
    assert "head" in out and "mean" in out and "2 frames" in out
    rows = {line.split()[0]: float(line.split()[1]) for line in out.splitlines()[1:]}
    assert rows["head"] < 0.01 and rows["left_knee"] < 0.01  # aligned on the right frames
    assert set(rows) == {"head", "left_hip", "left_knee", "right_knee", "mean"}
    assert main(["export", str(run)]) == 2
    assert "nothing to write" in capsys.readouterr().err
