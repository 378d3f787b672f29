"""A worker process killed in the middle of a run, on local two-worker Dask and Ray clusters: the engine runs the
run again (Dask's scheduler moves it to a live worker, Ray retries the task) and the numbers equal a run on one
process; where the engine gives up (no retries left), the experiment stops in one line and a rerun runs only the
missing runs."""
from __future__ import annotations

import os
import re
import signal
import threading
import time
from pathlib import Path

import pytest

from tests.app.test_compare import write_experiment
from tracker.app.compare import compare
from tracker.core.errors import InputError

pytestmark = [pytest.mark.slow, pytest.mark.optional]


def finished_numbers(out: Path) -> dict:
    """The estimated poses of each finished run (a killed worker's temporary folder is not a run)."""
    import numpy as np

    found = {}
    for d in (out / "runs").iterdir():
        if not d.name.startswith("."):
            with np.load(d / "estimates.npz") as a:
                found[d.name] = a["poses"].tobytes()
    return found


class RunKiller(threading.Thread):
    """Kills (SIGKILL) the worker process of the first run seen running in ``runs``: its temporary folder is named
    after the worker's process id, and its log is open from the run's start to its end (reading the sequence and
    building the prior take the run's first second)."""

    def __init__(self, runs: Path):
        super().__init__(daemon=True)
        self.runs, self.killed, self.done = runs, [], threading.Event()

    def run(self) -> None:
        while not self.done.is_set() and not self.killed:
            for d in self.runs.iterdir() if self.runs.is_dir() else ():
                found = re.match(r"\..+\.tmp-(\d+)$", d.name)
                log = d / "run.log"
                if found and int(found.group(1)) != os.getpid() and log.exists():
                    os.kill(int(found.group(1)), signal.SIGKILL)
                    self.killed.append(int(found.group(1)))
                    return
            time.sleep(0.005)

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.done.set()
        self.join()


def experiment(tmp_path: Path) -> Path:
    # 100 particles, 3 annealing layers, 3 tracked frames: long enough per run for the kill to land mid-run
    return write_experiment(tmp_path, priors=("zero-velocity",), seeds=2, tracking="particles = 100\nframes = 5")


def need(backend: str) -> None:
    pytest.importorskip("distributed" if backend == "dask" else "ray")


@pytest.mark.parametrize("backend", ["dask", "ray"])
def test_a_killed_worker_has_its_run_retried_by_the_engine(tmp_path, backend):
    need(backend)
    path = experiment(tmp_path)
    compare(path, tmp_path / "local", jobs=1, say=lambda s: None, progress=False)
    with RunKiller(tmp_path / backend / "runs") as killer:
        compare(path, tmp_path / backend, jobs=2, backend=backend, say=lambda s: None, progress=False)
    assert len(killer.killed) == 1
    assert finished_numbers(tmp_path / backend) == finished_numbers(tmp_path / "local")


@pytest.mark.parametrize("backend", ["dask", "ray"])
def test_without_retries_left_the_experiment_stops_in_one_line_and_reruns_only_missing_runs(tmp_path, backend,
                                                                                            monkeypatch):
    need(backend)
    if backend == "dask":
        import dask

        settings = dask.config.set({"distributed.scheduler.allowed-failures": 0})
    else:
        import contextlib

        import tracker.app.backends as backends_module

        monkeypatch.setattr(backends_module, "RAY_RETRIES", 0)
        settings = contextlib.nullcontext()
    path = experiment(tmp_path)
    out = tmp_path / "out"
    with settings, RunKiller(out / "runs") as killer:
        with pytest.raises(InputError, match="worker died too often .*finished runs are kept: run the same compare "
                                             "again") as stopped:
            compare(path, out, jobs=2, backend=backend, say=lambda s: None, progress=False)
    assert len(killer.killed) == 1 and "\n" not in str(stopped.value)
    finished = finished_numbers(out)
    said = []
    compare(path, out, jobs=1, say=said.append, progress=False)
    assert any(f"2 runs: {len(finished)} finished before (skipped), {2 - len(finished)} to run" in s for s in said)
    assert len(finished_numbers(out)) == 2
