"""``pose-tracker info``: what a sequence folder holds, as text and as JSON; a missing folder is one line."""
import json

import tracker
from tracker.app.cli import main


def test_info_says_what_a_synthetic_sequence_holds(synthetic_walk, capsys):
    seq = tracker.load_sequence(synthetic_walk.root)
    assert main(["info", str(synthetic_walk.root)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"{seq.root}: own layout, {seq.n_frames} frames, 60 Hz"
    assert out[1:5] == [f"  {c.name}: {c.width} x {c.height} pixels" for c in seq.rig.cameras]
    assert out[5] == "has: ground truth, background plates, body shape"


def test_info_as_json(synthetic_walk, capsys):
    assert main(["info", str(synthetic_walk.root), "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    seq = tracker.load_sequence(synthetic_walk.root)
    assert facts["frames"] == seq.n_frames and len(facts["cameras"]) == seq.n_views
    assert facts["ground truth"] is True and facts["keypoints"] is False


def test_info_of_a_missing_folder_is_one_line(tmp_path, capsys):
    assert main(["info", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sequence folder does not exist" in err[0]


def test_the_extending_guides_command_is_the_shipped_module():
    """The guide's worked example of a command is ``tracker/app/commands/info.py``, character for character."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    blocks = re.findall(r"```python\n(.*?)```", (root / "docs" / "guide" / "extending.md").read_text(), re.S)
    assert (root / "tracker" / "app" / "commands" / "info.py").read_text() in blocks
