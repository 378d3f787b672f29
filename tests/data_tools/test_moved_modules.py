"""The former flat module paths of ``data_tools`` (``data_tools.bvh``, ``data_tools.files``, ...) still import, as
aliases of the modules at their new paths, and warn when imported from outside the toolkit."""
from __future__ import annotations

import importlib
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import data_tools
from data_tools import MOVED, moved_to


@pytest.fixture
def no_aliases():
    """Forget the aliases imported so far (the modules themselves stay), so that an old path imports afresh."""
    def forget():
        for name in [n for n in sys.modules if moved_to(n) is not None]:
            del sys.modules[name]
    forget()
    yield
    forget()


def test_every_former_path_is_the_very_module_at_its_new_path(no_aliases):
    for old, new in MOVED.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            aliased = importlib.import_module(old)
        assert aliased is importlib.import_module(new), old
        assert aliased.__name__ == new and aliased.__spec__.name == new, old  # its own spec kept


def test_names_and_submodules_import_through_the_old_paths(no_aliases):
    from data_tools.motion.load import load_mocap as new_load_mocap
    from data_tools.vision.keypoints import readers as new_readers

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from data_tools.files import atomic_path
        from data_tools.keypoints.readers import import_keypoints
        from data_tools.load import load_mocap
        import data_tools.keypoints.layouts as layouts
    assert load_mocap is new_load_mocap and import_keypoints is new_readers.import_keypoints
    assert atomic_path is importlib.import_module("data_tools.io.files").atomic_path
    assert layouts is importlib.import_module("data_tools.vision.keypoints.layouts")
    assert data_tools.keypoints is importlib.import_module("data_tools.vision.keypoints")


def test_the_map_of_moves_covers_submodules_and_nothing_else():
    assert moved_to("data_tools.bvh") == "data_tools.motion.bvh"
    assert moved_to("data_tools.keypoints.detect") == "data_tools.vision.keypoints.detect"
    assert moved_to("data_tools.synth_settings") == "data_tools.synthesis.synth_settings"
    for name in ("data_tools", "data_tools.samples", "data_tools.motion.bvh", "data_tools.bvhx", "tracker.bvh"):
        assert moved_to(name) is None, name
    assert importlib.util.find_spec("data_tools.no_such_module") is None


def test_an_old_path_imported_from_outside_the_toolkit_warns_where_it_is_imported(no_aliases):
    with pytest.warns(DeprecationWarning, match=r"^data_tools\.bvh is now data_tools\.motion\.bvh; the old path is "
                                                r"removed in ") as caught:
        import data_tools.bvh  # noqa: F401
    assert [Path(w.filename) for w in caught] == [Path(__file__)]


def test_an_old_path_imported_from_the_toolkit_does_not_warn(no_aliases):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exec("import data_tools.trc\nfrom data_tools.sequence import read_sequence", {"__name__": "tracker.app.x"})
    assert sys.modules["data_tools.trc"] is importlib.import_module("data_tools.motion.trc")


def test_a_script_is_told_the_new_path_and_the_toolkit_imports_none_of_the_old():
    """In a fresh interpreter, as a user's script runs: the old path warns (Python shows a script's deprecation
    warnings), and importing the toolkit's layers imports no old path."""
    code = ("import sys, data_tools.motion.load, data_tools.sequences.sequence, data_tools.synthesis.synth, "
            "data_tools.vision.video, data_tools.vision.keypoints.readers\n"
            "from data_tools import moved_to\n"
            "assert not [n for n in sys.modules if moved_to(n)], [n for n in sys.modules if moved_to(n)]\n"
            "import data_tools.files\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=Path(__file__).resolve().parents[2])
    assert run.returncode == 0, run.stderr
    assert "DeprecationWarning: data_tools.files is now data_tools.io.files" in run.stderr


def test_the_toolkit_imports_data_tools_by_its_layers():
    """No module of the toolkit, its benchmarks or its tests imports a former path (this file aside): the
    aliases are for users' scripts, one version long."""
    import re

    root = Path(__file__).resolve().parents[2]
    pattern = re.compile(r"^\s*(?:from|import)\s+(" + "|".join(re.escape(old) for old in MOVED) + r")(?![\w])",
                         re.M)
    found = []
    for folder in ("tracker", "priors", "likelihoods", "data_tools", "benchmarks", "tests", "examples"):
        for path in (root / folder).rglob("*.py"):
            if path.resolve() == Path(__file__).resolve():
                continue
            found += [f"{path.relative_to(root)}: {m.group(1)}" for m in pattern.finditer(path.read_text())]
    assert not found, found
