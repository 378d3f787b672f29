"""Every code block of the README runs as written, on a tiny setting (fewer frames, epochs and particles).

The install and test commands are the ones CI runs (``.ci/run``); the experiment commands name files that
exist; everything else is run here, in the order the README gives it.
"""
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from data_tools.motion.fetch import CMU_FOLDER, parse_trial
from tracker.app.experiment import DATA_ROOT_ENV
from tracker.app.fetching import experiment_needs

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"
#: What the test shrinks, and to what: each must appear in its block, so the README cannot drift from the test.
TINY_PYTHON = {"frames=60": "frames=6", "epochs=100": "epochs=2", "particles=500": "particles=30"}
TINY_SHELL = {"pose-tracker demo": "pose-tracker demo --frames 6", "--frame 40": "--frame 4",
              "--particles 2000": "--particles 200", "--frames 150": "--frames 6",
              "--out crbm.pt": "--order 1 --epochs 2 --out crbm.pt"}


def blocks(language: str) -> list[str]:
    """The README's fenced code blocks of ``language`` ("" for those without one), fences paired in order."""
    found, lines, inside = [], [], None
    for line in README.read_text().splitlines(keepends=True):
        if line.startswith("```"):
            if inside is None:
                inside, lines = line[3:].strip(), []
            else:
                if inside == language:
                    found.append("".join(lines))
                inside = None
        elif inside is not None:
            lines.append(line)
    return found


def readme_fetch() -> tuple[Path, list[str]]:
    """The data root and the trials of the one ``pose-tracker fetch cmu ...`` command the README's text names."""
    (command,) = re.findall(r"`(pose-tracker fetch cmu [^`]*)`", README.read_text())
    words = shlex.split(command)
    at = words.index("--data-root")
    return Path(words[at + 1]), words[3:at]


def fetched_files() -> list[Path]:
    """Where the README's fetch puts its files (skeletons and motions), relative to the folder it runs in."""
    root, trials = readme_fetch()
    return list(dict.fromkeys(root / CMU_FOLDER / f for t in trials for f in parse_trial(t).files()))


def commands(block: str) -> list[str]:
    """The block's command lines, comments and continuation lines joined."""
    text = re.sub(r"\\\n\s*", " ", block)
    return [line.split("  #")[0].strip() for line in text.splitlines() if line.strip()]


@pytest.mark.slow
def test_the_readme_python_block_runs(tmp_path, monkeypatch, capsys):
    (code,) = blocks("python")
    for big, small in TINY_PYTHON.items():
        assert big in code, big
        code = code.replace(big, small)
    torch.set_num_threads(1)
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    printed = capsys.readouterr().out.split()
    assert float(printed[0]) > 0 and float(printed[1]) > 0  # marker error (mm) and seconds per frame
    assert (tmp_path / "run" / "result.json").is_file() and (tmp_path / "crbm1.pt").is_file()


def test_the_install_and_test_commands_are_what_ci_runs():
    install, tests = blocks("")[:2]
    ci = (REPO / ".ci" / "run").read_text()
    for command in commands(install)[0].split(" && ") + commands(tests)[0].split(" && "):
        ci_form = command.replace("pip install", "python -m pip install").replace("pose-tracker demo",
                                                                                  "python -m tracker demo")
        assert ci_form in ci or command in ci, command


def test_the_experiment_commands_name_files_that_exist():
    named = [word for block in blocks("") for line in commands(block) if "compare" in line or "bash " in line
             for word in shlex.split(line) if word.startswith("benchmarks/")]
    assert named
    for path in named:
        assert (REPO / path).is_file(), path


def test_the_own_mocap_block_names_the_files_where_the_fetch_before_it_puts_them():
    (block,) = [b for b in blocks("") if "--mocap" in b]
    named = [Path(word) for line in commands(block) for word in shlex.split(line) if word.endswith(".amc")]
    placed = fetched_files()
    assert named and set(named) <= set(placed), set(named) - set(placed)


def test_the_fetch_for_line_says_where_the_files_go(monkeypatch):
    """The shipped experiment's data root is outside the checkout: the line says so, naming it."""
    monkeypatch.delenv(DATA_ROOT_ENV, raising=False)
    (line,) = [line for block in blocks("") for line in block.splitlines() if line.startswith("pose-tracker fetch")]
    command, comment = line.split("  #")
    root, _, _ = experiment_needs(REPO / shlex.split(command)[3])
    where = os.path.relpath(root, REPO)
    assert where.startswith("..") and f"into {where}, outside the checkout" in comment, (where, comment)


@pytest.mark.slow
def test_the_readme_shell_blocks_run(tmp_path, mocap_dir):
    """The demo, then the first tracking runs on what it left, then the own-mocap block on shared clips placed
    where the README's fetch puts them."""
    root, _ = readme_fetch()
    for file in fetched_files():
        (tmp_path / file).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / file).symlink_to(mocap_dir / file.relative_to(root / CMU_FOLDER))
    runnable = [b for b in blocks("") if "pose-tracker" in b and "compare" not in b and "bash " not in b
                and "pose-tracker capture" not in b]
    used = set()
    script = []
    for block in runnable:
        for line in commands(block):
            for part in line.split(" && "):
                if part.startswith("pip install"):
                    continue  # the install itself: what CI runs, checked above
                for big, small in TINY_SHELL.items():
                    if big in part:
                        part, _ = part.replace(big, small), used.add(big)
                script.append(part)
    assert used == set(TINY_SHELL), set(TINY_SHELL) - used
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    for part in script:
        argv = [sys.executable, "-m", "tracker", "--threads", "1"] + shlex.split(part)[1:]
        done = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"{part}\n{done.stderr[-2000:]}"
    for produced in ("runs/pretrained/result.json", "frame40.png", "runs/zv/result.json", "walk16/cameras.json",
                     "crbm.pt", "runs/mixture/result.json"):
        assert (tmp_path / produced).exists(), produced


def test_the_readme_capture_line_parses():
    """The real-video block names videos the reader has, not the test: its command line must parse as written
    (capture itself runs end to end in tests/app/test_capture.py)."""
    from tracker.app.parser import parse_arguments

    (line,) = [line for block in blocks("") for line in commands(block) if line.startswith("pose-tracker capture")]
    args = parse_arguments(shlex.split(line)[1:])
    assert args.command == "capture" and len(args.videos) == 4 and args.out == "take1"
