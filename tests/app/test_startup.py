"""What the command line imports: help and tracking do not load the libraries only other commands need.

Each case runs the command line's ``main`` in a fresh interpreter and lists which of the heavy libraries ended
up in ``sys.modules`` (an import check, not a timing).
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

#: Libraries that only rendering (trimesh), plots (matplotlib) and videos (av) need.
RENDERING = ("trimesh", "matplotlib", "av")
#: What the help texts do without: the above, torch (the learned priors' models load when one is built), and the
#: compiled and image code of tracking (numba, OpenCV, scipy).
NOT_FOR_HELP = ("torch", "numba", "cv2", "scipy", *RENDERING)

_PROGRAM = """
import json, sys
from tracker.app.cli import main
try:
    status = main({args!r})
except SystemExit as exc:
    status = exc.code
print(json.dumps({{"status": status, "loaded": sorted(m for m in {modules!r} if m in sys.modules)}}))
"""


def loaded_by(args: list[str], modules: tuple[str, ...], cwd: Path) -> list[str]:
    """Which of ``modules`` a fresh interpreter has imported after ``main(args)`` (which must succeed)."""
    out = subprocess.run([sys.executable, "-c", _PROGRAM.format(args=args, modules=modules)], capture_output=True,
                         text=True, cwd=cwd)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report["status"] in (0, None), out.stderr
    return report["loaded"]


@pytest.mark.parametrize("args", [["--help"], ["track", "--help"], ["track", "--prior", "crbm", "--help"],
                                  ["train", "--help"]])
def test_help_loads_no_model_tracking_or_rendering_library(args, tmp_path):
    assert loaded_by(args, NOT_FOR_HELP, tmp_path) == []


@pytest.mark.slow
def test_zero_velocity_track_loads_no_renderer_and_no_torch(bodytrack_dir, tmp_path):
    out = tmp_path / "run"
    args = ["track", str(bodytrack_dir), "--prior", "zero-velocity", "--frames", "1", "--particles", "50",
            "--out", str(out), "--quiet"]
    assert loaded_by(args, ("torch", *RENDERING), tmp_path) == []
    assert (out / "result.json").is_file()


@pytest.mark.parametrize("package", ["priors", "likelihoods"])
def test_builtin_modules_are_exactly_the_registering_ones(package):
    """The modules load_plugins imports each register something, and no other module of the package registers
    anything (a registering module missing from the list would vanish from the command line)."""
    import importlib
    import pkgutil

    from tracker.engine.registry import LIKELIHOODS, PRIORS

    pkg = importlib.import_module(package)
    modules = {info.name for info in pkgutil.walk_packages(pkg.__path__, f"{package}.")}
    assert set(pkg.BUILTIN_MODULES) <= modules
    for name in sorted(modules):
        importlib.import_module(name)
    origins = {e.build.__module__ for e in [*PRIORS.entries.values(), *LIKELIHOODS.entries.values()]}
    assert {o for o in origins if o.startswith(f"{package}.")} == set(pkg.BUILTIN_MODULES)



@pytest.mark.slow
def test_a_learned_prior_built_after_set_threads_gets_the_run_threads(walk_32_frames, tmp_path):
    """Torch is imported only when a learned prior is built, after the command line gave the run its threads:
    building the prior gives torch that count (torch's own default is one thread per core)."""
    model = Path(__file__).parents[1] / "data" / "crbm3_paced_v0.13.pt"
    program = f"""
import sys
import tracker
from tracker.app.api import build_prior
sequence = tracker.load_sequence({str(walk_32_frames.root)!r})
tracker.set_threads(1)
assert "torch" not in sys.modules
import torch
torch.set_num_threads(2)  # what torch would start with on a machine of two cores or more
build_prior("crbm", sequence, [{str(model)!r}])
print(torch.get_num_threads())
"""
    out = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["1"]
