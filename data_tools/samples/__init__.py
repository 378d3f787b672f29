"""Small sample data shipped with the package for the built-in demo (see ATTRIBUTION.md in each folder)."""
from __future__ import annotations

from pathlib import Path

SAMPLES = Path(__file__).resolve().parent

#: The CMU attribution that must accompany the sample data and anything converted from it.
CMU_ATTRIBUTION = ("The data used in this project was obtained from mocap.cs.cmu.edu. "
                   "The database was created with funding from NSF EIA-0196217.")


def sample_walks() -> tuple[Path, list[Path]]:
    """The shipped CMU subject-7 skeleton and walk clips (ASF, [AMC, ...])."""
    folder = SAMPLES / "cmu07"
    return folder / "07.asf", sorted(folder.glob("*.amc"))
