"""Mocap readers (ASF/AMC, BVH), retargeting to the body model, sequence formats. Imports only ``tracker``.

The package is laid out by layer; a layer imports only the layers below it (``pyproject.toml``'s import-linter
contracts)::

    vision | synthesis   video files in, person segmentation, landmarks, 2-D keypoints | rendered sequences
    sequences            multi-view sequences on disk: cameras, images, keypoint files, pose files, references
    motion               motion capture: readers by suffix, retargeting, the converted-clip cache, corpora
    io                   checked reading of text, JSON and npz; atomic writes; content fingerprints

``samples`` is shipped data (two CMU trials), not a layer.

The modules used to sit flat in this package (``data_tools.bvh``, ``data_tools.files``, ...). Those names still
import, for one more release, as aliases of the moved modules (:data:`MOVED`): the very same module object, so
there is never a second copy of a module's state. Imported from outside the toolkit's own packages, an old name
raises a :class:`DeprecationWarning` naming the new one.
"""
from __future__ import annotations

import sys
from importlib import import_module
from importlib.machinery import ModuleSpec
from importlib.util import find_spec
from types import ModuleType
from typing import Sequence

#: Former module paths -> where they live now. A package's entry covers its submodules too
#: (``data_tools.keypoints.readers`` -> ``data_tools.vision.keypoints.readers``).
MOVED: dict[str, str] = {
    "data_tools.checks": "data_tools.io.checks",
    "data_tools.files": "data_tools.io.files",
    "data_tools.fingerprints": "data_tools.io.fingerprints",
    "data_tools.textfiles": "data_tools.io.textfiles",
    "data_tools.asf_amc": "data_tools.motion.asf_amc",
    "data_tools.bvh": "data_tools.motion.bvh",
    "data_tools.bvh_export": "data_tools.motion.bvh_export",
    "data_tools.cache": "data_tools.motion.cache",
    "data_tools.clip_io": "data_tools.motion.clip_io",
    "data_tools.cmu_trials": "data_tools.motion.cmu_trials",
    "data_tools.corpus": "data_tools.motion.corpus",
    "data_tools.fetch": "data_tools.motion.fetch",
    "data_tools.joint_names": "data_tools.motion.joint_names",
    "data_tools.load": "data_tools.motion.load",
    "data_tools.mocap": "data_tools.motion.mocap",
    "data_tools.readers": "data_tools.motion.readers",
    "data_tools.retarget": "data_tools.motion.retarget",
    "data_tools.skeleton_points": "data_tools.motion.skeleton_points",
    "data_tools.transition": "data_tools.motion.transition",
    "data_tools.trc": "data_tools.motion.trc",
    "data_tools.bodytrack": "data_tools.sequences.bodytrack",
    "data_tools.calibration": "data_tools.sequences.calibration",
    "data_tools.estimates": "data_tools.sequences.estimates",
    "data_tools.keypoint_file": "data_tools.sequences.keypoint_file",
    "data_tools.reference": "data_tools.sequences.reference",
    "data_tools.rig_formats": "data_tools.sequences.rig_formats",
    "data_tools.sequence": "data_tools.sequences.sequence",
    "data_tools.raster": "data_tools.synthesis.raster",
    "data_tools.render": "data_tools.synthesis.render",
    "data_tools.synth": "data_tools.synthesis.synth",
    "data_tools.synth_settings": "data_tools.synthesis.synth_settings",
    "data_tools.keypoints": "data_tools.vision.keypoints",
    "data_tools.landmarks": "data_tools.vision.landmarks",
    "data_tools.person_segmentation": "data_tools.vision.person_segmentation",
    "data_tools.video": "data_tools.vision.video",
}

#: The release that drops the old names.
REMOVED_IN = "0.24"

#: The toolkit's own top-level packages: an old name imported from one of them raises no warning.
_OWN = ("tracker", "priors", "likelihoods", "data_tools")


def moved_to(name: str) -> str | None:
    """The current path of the former module path ``name`` (or of a submodule of a former package), None for a
    name that did not move."""
    parts = name.split(".")
    for end in range(len(parts), 1, -1):
        old = ".".join(parts[:end])
        if old in MOVED:
            return ".".join([MOVED[old], *parts[end:]])
    return None


def _importer(frame) -> tuple[str, int]:
    """The module name of the first frame above ``frame`` that is not the import machinery or this module, and
    the ``stacklevel`` that points a warning raised in ``frame`` at it (:func:`warnings.warn` skips the frames of
    ``importlib._bootstrap`` itself)."""
    level = 1
    while frame is not None:
        name, filename = frame.f_globals.get("__name__", ""), frame.f_code.co_filename
        bootstrap = "importlib" in filename and "_bootstrap" in filename
        if not (bootstrap or name == "importlib" or name.startswith("importlib.") or frame.f_globals is globals()):
            return name, level
        frame, level = frame.f_back, level + (not bootstrap)
    return "", level


class _MovedModules:
    """A ``sys.meta_path`` finder and loader that answers a former module path with the module now at its new
    path (imported there if need be), warning when the import comes from outside the toolkit."""

    def __init__(self) -> None:
        #: The real specs of modules being aliased: importlib stamps the alias's spec on the module it is given.
        self._real_specs: dict[str, ModuleSpec | None] = {}

    def find_spec(self, fullname: str, path: Sequence[str] | None = None,
                  target: ModuleType | None = None) -> ModuleSpec | None:
        new = moved_to(fullname)
        if new is None:
            return None
        real = find_spec(new)
        if real is None:
            return None
        return ModuleSpec(fullname, self, is_package=real.submodule_search_locations is not None)

    def create_module(self, spec: ModuleSpec) -> ModuleType:
        new = moved_to(spec.name)
        module = import_module(new)
        importer, level = _importer(sys._getframe(0))
        if importer.partition(".")[0] not in _OWN:
            import warnings

            warnings.warn(f"{spec.name} is now {new}; the old path is removed in {REMOVED_IN}",
                          DeprecationWarning, stacklevel=level)
        self._real_specs[spec.name] = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run (the module ran at its new path): its own spec put back."""
        module.__spec__ = self._real_specs.pop(module.__spec__.name)


if not any(type(finder).__qualname__ == _MovedModules.__qualname__ and type(finder).__module__ == __name__
           for finder in sys.meta_path):  # once, even when this module is reloaded
    sys.meta_path.insert(0, _MovedModules())
