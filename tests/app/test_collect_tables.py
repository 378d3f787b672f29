"""benchmarks/collect_tables.py: a compare output folder replaces its experiment's section of the results file and
leaves every other section as it was."""
import importlib.util
import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("collect_tables", REPO / "benchmarks" / "collect_tables.py")
collect_tables = importlib.util.module_from_spec(spec)
spec.loader.exec_module(collect_tables)


def output_folder(root: Path, name: str, experiment: str, number: str, version: str | None = "9.9.9") -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    (folder / "table.md").write_text(f"# {name}\n\n`x.toml`: 1 seed(s)\n\n## Marker error (mm)\n\n| prior | walk |\n"
                                     f"|---|---|\n| zero-velocity | {number} |\n")
    meta = {"experiment": f"/elsewhere/checkout/benchmarks/experiments/{experiment}", "description": name}
    if version:
        meta["version"] = version
    (folder / "experiment.json").write_text(json.dumps(meta))
    return folder


def test_a_rerun_replaces_only_its_own_section(tmp_path):
    out = tmp_path / "results.md"
    out.write_text("# Results\n\nHand-written preamble.\n\n<!-- experiment: benchmarks/experiments/a.toml -->\n"
                   "## `a.toml`\n\nold a\n\n<!-- experiment: benchmarks/experiments/study/tuning_02.toml -->\n"
                   "## `study/tuning_02.toml`\n\nkept by hand\n\n<!-- experiment: benchmarks/experiments/z.toml -->\n"
                   "## `z.toml`\n\nold z\n")
    a = output_folder(tmp_path, "a_out", "a.toml", "12.3")
    new = output_folder(tmp_path, "new_out", "study/test_leave_out_16.toml", "45.6", version=None)
    collect_tables.main([str(a), str(new), "--out", str(out)])
    text = out.read_text()
    assert text.startswith("# Results\n\nHand-written preamble.\n")
    assert "old a" not in text and "| zero-velocity | 12.3 |" in text and "Made with pose-tracker 9.9.9." in text
    assert "python -m tracker compare benchmarks/experiments/a.toml --out results/a_out --jobs 2" in text
    assert "kept by hand" in text and "old z" in text
    keys = [k for k, _ in collect_tables.split_sections(text)[1]]
    assert keys == ["benchmarks/experiments/a.toml", "benchmarks/experiments/study/tuning_02.toml",
                    "benchmarks/experiments/study/test_leave_out_16.toml", "benchmarks/experiments/z.toml"]
    assert "not recorded in experiment.json" in text  # the folder without a version says so
    once = out.read_text()
    collect_tables.main([str(a), "--out", str(out)])
    assert out.read_text() == once  # the same folder again changes nothing


def test_a_folder_that_is_not_a_compare_output_is_one_line_and_exit_2(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit) as stop:
        collect_tables.main([str(tmp_path / "empty"), "--out", str(tmp_path / "results.md")])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no table.md" in err[0] and str(tmp_path / "empty") in err[0]
    assert not (tmp_path / "results.md").exists()
