"""The README's Python block runs as written (on a tiny setting: fewer frames, epochs and particles)."""
import re
from pathlib import Path

import torch

README = Path(__file__).resolve().parents[1] / "README.md"
#: What the test shrinks, and to what: each must appear in the block, so the block cannot drift from the test.
TINY = {"frames=60": "frames=6", "epochs=100": "epochs=2", "particles=500": "particles=30"}


def test_the_readme_python_block_runs(tmp_path, monkeypatch, capsys):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) == 1
    code = blocks[0]
    for big, small in TINY.items():
        assert big in code, big
        code = code.replace(big, small)
    torch.set_num_threads(1)
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    printed = capsys.readouterr().out.split()
    assert float(printed[0]) > 0 and float(printed[1]) > 0  # marker error (mm) and seconds per frame
    assert (tmp_path / "run" / "result.json").is_file() and (tmp_path / "crbm1.pt").is_file()
