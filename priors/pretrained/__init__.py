"""Model files shipped with the package, so that ``pose-tracker track DIR --prior mixture`` works from a fresh
install without a model file and without training.

They are trained only on the CMU Graphics Lab Motion Capture Database's trials, whose terms allow
redistributing models made from them (never on data of a non-commercial licence). How each was made (the
command, the clips, the seed) and its attribution are in docs/reference/priors.md.

The data used in this project was obtained from mocap.cs.cmu.edu.
The database was created with funding from NSF EIA-0196217.
"""
from __future__ import annotations

from pathlib import Path

from tracker.core.errors import InputError

#: The folder of the shipped model files (package data).
FOLDER = Path(__file__).resolve().parent
#: The mixture's components when it is given no model file: the shipped learned prior and zero-velocity.
MIXTURE_COMPONENTS = "neural,zero-velocity"
#: The shipped model file of the mixture's learned component.
MIXTURE_MODEL = "neural_cmu.pt"


def mixture_model() -> Path:
    """The shipped model file of the mixture's learned component; an install without it is an
    :class:`InputError` saying how to give one."""
    path = FOLDER / MIXTURE_MODEL
    if not path.is_file():
        raise InputError("the package's pretrained model is missing (a damaged install?); give a model file "
                         "with --model, or reinstall pose-tracker", path)
    return path
