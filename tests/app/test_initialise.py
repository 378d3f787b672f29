"""The body's place, size and first pose found from the first frame's silhouettes of a rendered walk."""
from __future__ import annotations

import json

import numpy as np
import pytest

from data_tools.sequences.sequence import read_sequence
from data_tools.synthesis.synth import SynthConfig, synthesize
from tracker.app.cli import main
from tracker.app.initialise import scaled_shape
from tracker.core.body import default_shape, fifteen_cone_model, stance_pose
from tracker.core.kinematics import markers, standing_height


def test_scaled_shape_scales_the_standing_height():
    ratio = standing_height(fifteen_cone_model(scaled_shape(default_shape(), 1.1))) / standing_height(
        fifteen_cone_model())
    assert abs(ratio - 1.1) < 1e-6
    model = fifteen_cone_model()
    t_pose = markers(model, stance_pose(model, np.pi / 2)[None])[0]
    wrist, shoulder = model.marker_names.index("left_wrist"), model.marker_names.index("left_shoulder")
    assert abs(t_pose[wrist, 2] - t_pose[shoulder, 2]) < 1.0 and t_pose[wrist, 1] > t_pose[shoulder, 1] + 500


@pytest.mark.slow
def test_initialise_places_the_body_on_the_person(tmp_path, walk_07_11, capsys):
    synthesize(walk_07_11, tmp_path / "seq", SynthConfig(views=4, frames=2, width=320, height=240, seed=1))
    truth = read_sequence(tmp_path / "seq").groundtruth
    assert main(["initialise", str(tmp_path / "seq"), "--out", str(tmp_path / "init.npz")]) == 0
    assert "first pose" in capsys.readouterr().out
    seq = read_sequence(tmp_path / "seq")  # now with the fitted shape from meta.json
    assert "body_shape" in json.loads((tmp_path / "seq" / "meta.json").read_text())
    poses = np.load(tmp_path / "init.npz")["poses"]
    assert poses.shape == (2, seq.model.n_dofs)
    found = markers(seq.model, poses[:1])[0]
    errors = np.linalg.norm(found - truth.markers[0], axis=-1)
    torso = [seq.model.marker_names.index(n) for n in ("pelvis", "thorax", "head")]
    assert errors[torso].max() < 150.0  # mm: placed on the person
    height = standing_height(seq.model)
    assert 0.8 < height / standing_height(fifteen_cone_model()) < 1.2
