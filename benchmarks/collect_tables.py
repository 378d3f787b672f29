"""Write finished experiments' tables into docs/results.md (run by hand after `compare`).

    python benchmarks/collect_tables.py RESULTS/NAME [RESULTS/NAME ...] [--out docs/results.md]

Each RESULTS/NAME is an output folder of `python -m tracker compare EXPERIMENT --out RESULTS/NAME` (it holds
table.md and experiment.json). The results file is a preamble followed by one section per experiment file, each
opened by a line ``<!-- experiment: benchmarks/experiments/... -->``. A given folder's section (the experiment
file, its description, the command that reproduces it, the package version its runs were made with, as
experiment.json records it, and its tables) replaces the section of the same experiment file, or is added after
the sections of its folder (at the end when there are none); every other section is kept as it is, so rerunning
one experiment updates only its own section. A folder's per_frame.png is linked when a copy of it is in
docs/figures/NAME.png (``--figures`` copies it there).
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MARKER = re.compile(r"^<!-- experiment: (?P<key>\S+) -->$", re.MULTILINE)
EXPERIMENTS = "benchmarks/experiments/"


def split_sections(text: str) -> tuple[str, list[tuple[str, str]]]:
    """The preamble and the (experiment key, section text) pairs of a results file, in order."""
    marks = list(MARKER.finditer(text))
    if not marks:
        return text, []
    sections = [(m.group("key"), text[m.start():(marks[i + 1].start() if i + 1 < len(marks) else len(text))])
                for i, m in enumerate(marks)]
    return text[:marks[0].start()], sections


def experiment_key(recorded: str) -> str:
    """The experiment file as a path from the repository root (experiment.json records the absolute path of the
    checkout it ran in, which may be another one)."""
    path = Path(recorded)
    try:
        return path.resolve().relative_to(REPO).as_posix()
    except ValueError:
        text = path.as_posix()
        return text[text.index(EXPERIMENTS):] if EXPERIMENTS in text else text


def fail(message: str) -> None:
    """One line on stderr and exit status 2, as the command line does for bad input."""
    print(f"collect_tables: {message}", file=sys.stderr)
    raise SystemExit(2)


def section(folder: Path, figures: Path) -> tuple[str, str]:
    """The experiment key and the results section of one `compare` output folder."""
    for name in ("table.md", "experiment.json"):
        if not (folder / name).is_file():
            fail(f"{folder}: no {name} (not a finished `compare` output folder)")
    try:
        meta = json.loads((folder / "experiment.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        fail(f"{folder / 'experiment.json'}: cannot be read ({exc})")
    if "experiment" not in meta:
        fail(f"{folder / 'experiment.json'}: names no experiment file")
    key = experiment_key(meta["experiment"])
    version = meta.get("version")
    lines = (folder / "table.md").read_text(encoding="utf-8").rstrip().splitlines()
    body = "\n".join("#" + line if line.startswith("## ") else line for line in lines[1:]).strip()
    title = key[len(EXPERIMENTS):] if key.startswith(EXPERIMENTS) else key
    parts = [f"<!-- experiment: {key} -->", f"## `{title}`", ""]
    if meta.get("description"):
        parts += [meta["description"], ""]
    parts += [f"Made with pose-tracker {version}." if version else
              "The package version that made these runs is not recorded in experiment.json.", "",
              "```", f"python -m tracker compare {key} --out results/{folder.name} --jobs 2", "```", "", body, ""]
    if (figures / f"{folder.name}.png").is_file():
        parts += [f"![per-frame error, mean over seeds with a band of one std](figures/{folder.name}.png)", ""]
    return key, "\n".join(parts) + "\n"


def merge(sections: list[tuple[str, str]], key: str, text: str) -> list[tuple[str, str]]:
    """``sections`` with ``key``'s section replaced by ``text``, or ``text`` inserted after the last section of
    the same folder (appended when there is none)."""
    keys = [k for k, _ in sections]
    if key in keys:
        return [(k, text if k == key else t) for k, t in sections]
    folder = key.rsplit("/", 1)[0] + "/"
    near = [i for i, k in enumerate(keys) if k.startswith(folder) or folder.startswith(k.rstrip("/") + "/")]
    at = near[-1] + 1 if near else len(sections)
    return sections[:at] + [(key, text)] + sections[at:]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path, help="compare output folders")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "results.md")
    parser.add_argument("--figures", action="store_true",
                        help="copy each folder's per_frame.png to docs/figures/NAME.png and link it")
    args = parser.parse_args(argv)
    from data_tools.io.files import write_text_atomic

    figures = args.out.parent / "figures"
    text = args.out.read_text(encoding="utf-8") if args.out.exists() else "# Results\n\n"
    preamble, sections = split_sections(text)
    for folder in args.folders:
        if args.figures and (folder / "per_frame.png").is_file():
            figures.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(folder / "per_frame.png", figures / f"{folder.name}.png")
        key, new = section(folder, figures)
        sections = merge(sections, key, new)
        print(f"{key} <- {folder}")
    out = preamble + "".join(t if t.endswith("\n\n") else t.rstrip("\n") + "\n\n" for _, t in sections)
    write_text_atomic(args.out, out.rstrip("\n") + "\n")
    print(f"{len(sections)} section(s) -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
