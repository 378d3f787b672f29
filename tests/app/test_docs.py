"""The documentation matches the code: the command reference is the parsers' help, links lead somewhere, and
nothing addressed to users speaks of how the project was developed instead of what it does."""
import re
import subprocess
import sys
from pathlib import Path

import pytest


REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
#: Words that belong to the project's development log, not to its users (the version history is CHANGELOG.md).
DIARY = re.compile(r"session [0-9]|next session|round [0-9]|issue [0-9]", re.IGNORECASE)
PACKAGES = ("tracker", "priors", "likelihoods", "data_tools")


def user_texts() -> list[Path]:
    texts = [REPO / "README.md", *sorted(DOCS.rglob("*.md"))]
    for package in PACKAGES:
        texts += sorted((REPO / package).rglob("*.py"))
    return texts


def generated_reference() -> str:
    """The reference as the command writes it, in a process of its own (tests register toy plugins in this one)."""
    done = subprocess.run([sys.executable, "-m", "tracker.app.cli_reference"], capture_output=True, text=True,
                          cwd=REPO, check=True)
    return done.stdout


@pytest.mark.slow
def test_the_command_reference_is_the_parsers_help():
    written = (DOCS / "reference" / "cli.md").read_text()
    assert written == generated_reference(), ("docs/reference/cli.md is out of date: "
                                              "python -m tracker.app.cli_reference > docs/reference/cli.md")


@pytest.mark.parametrize("path", user_texts(), ids=lambda p: str(p.relative_to(REPO)))
def test_user_texts_do_not_read_as_a_development_log(path):
    found = [line.strip() for line in path.read_text().splitlines() if DIARY.search(line)]
    assert not found, found[:3]


def test_help_texts_do_not_read_as_a_development_log():
    found = [line for line in generated_reference().splitlines() if DIARY.search(line)]
    assert not found, found[:3]


def markdown_links(path: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    return [target for target in re.findall(r"\]\(([^)\s]+)\)", text)
            if not re.match(r"[a-z]+:", target) and not target.startswith("#")]


@pytest.mark.parametrize("path", [REPO / "README.md", REPO / "CHANGELOG.md", *sorted(DOCS.rglob("*.md"))],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_links_lead_to_files_that_exist(path):
    missing = [t for t in markdown_links(path) if not (path.parent / t.split("#")[0]).exists()]
    assert not missing, missing


def test_paths_the_readme_names_exist():
    named = re.findall(r"`((?:docs|benchmarks|examples|data_tools|tracker)/[^`\s]*)`", (REPO / "README.md").read_text())
    assert named
    missing = [p for p in named if not (REPO / p.rstrip("/")).exists()]
    assert not missing, missing
