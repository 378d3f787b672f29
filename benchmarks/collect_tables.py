"""Gather the tables of finished experiments into docs/experiments.md (run by hand after `compare`).

    python benchmarks/collect_tables.py RESULTS_ROOT [--notes docs/experiment_notes.md]

RESULTS_ROOT holds one output folder per experiment (as written by `python -m tracker compare EXP --out
RESULTS_ROOT/NAME`). Each folder's table.md goes in with the command that made it; the notes file (findings
written by hand) goes first. Each folder's per_frame.png is linked when it was copied to
docs/figures/NAME.png.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path)
    parser.add_argument("--notes", type=Path, default=REPO / "docs" / "experiment_notes.md")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "experiments.md")
    args = parser.parse_args()
    parts = [args.notes.read_text().rstrip() + "\n"] if args.notes.exists() else []
    folders = [p for p in args.root.iterdir() if (p / "table.md").exists()]
    for folder in sorted(folders, key=lambda p: (not p.name.startswith("table"), p.name != "monocular", p.name)):
        meta = json.loads((folder / "experiment.json").read_text())
        experiment = Path(meta["experiment"])
        try:
            experiment = experiment.relative_to(REPO)
        except ValueError:
            pass
        table = (folder / "table.md").read_text().replace("\n# ", "\n## ").lstrip("# ").rstrip()
        parts.append(f"\n---\n\n## {table.splitlines()[0]}\n\n```\npython -m tracker compare {experiment} "
                     f"--out results/{folder.name} --jobs 2\n```\n\n" + "\n".join(
                         line.replace("## ", "### ", 1) if line.startswith("## ") else line
                         for line in table.splitlines()[1:]).strip() + "\n"
                     + (f"\n![per-frame error, mean over seeds with a band of one std](figures/{folder.name}.png)\n"
                        if (args.out.parent / "figures" / f"{folder.name}.png").exists() else ""))
    args.out.write_text("\n".join(parts))
    print(f"{len(parts)} part(s) -> {args.out}")


if __name__ == "__main__":
    main()
