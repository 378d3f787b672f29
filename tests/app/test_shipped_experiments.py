"""Every shipped experiment file is valid for this version: `compare` checks the whole file before it runs
anything, so a file that names an option or a prior the package no longer has would fail at once."""
from pathlib import Path

import pytest

from tracker.app.experiment import load_experiment

pytestmark = pytest.mark.shared

REPO = Path(__file__).resolve().parents[2]
EXPERIMENTS = REPO / "benchmarks" / "experiments"
#: Protocols whose sequences and models a script makes first (their folders hold a prepare.sh).
PREPARED = {p.parent for p in EXPERIMENTS.rglob("prepare.sh")}
FILES = sorted(p for p in EXPERIMENTS.rglob("*.toml") if not PREPARED & set(p.parents))


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(EXPERIMENTS)))
def test_a_shipped_experiment_file_is_valid(path):
    if not (REPO.parent / "shared").is_dir():
        pytest.skip("the experiment files name data in ../shared beside the checkout")
    experiment = load_experiment(path)
    assert experiment.priors and experiment.sequences
