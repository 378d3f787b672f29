"""Small sample data shipped with the package, for the built-in demo and first experiments (see ATTRIBUTION.md in
each folder)."""
from __future__ import annotations

from pathlib import Path

SAMPLES = Path(__file__).resolve().parent

#: The CMU attribution that must accompany the sample data and anything converted from it.
CMU_ATTRIBUTION = ("The data used in this project was obtained from mocap.cs.cmu.edu. "
                   "The database was created with funding from NSF EIA-0196217.")

#: The CMU subjects shipped, each in its folder ``cmu<NN>`` with its ASF and its walks.
SAMPLE_SUBJECTS = (7, 2)


def sample_walks(subject: int = 7) -> tuple[Path, list[Path]]:
    """A shipped CMU subject's skeleton and walk clips (ASF, [AMC, ...]): subject 7 (the default; walks 07_01
    and 07_02) or subject 2 (walk 02_01, another person, for trying a prior on someone it never saw)."""
    if subject not in SAMPLE_SUBJECTS:
        raise ValueError(f"no shipped walks of CMU subject {subject}; the shipped subjects are "
                         f"{', '.join(map(str, SAMPLE_SUBJECTS))}")
    folder = SAMPLES / f"cmu{subject:02d}"
    return folder / f"{subject:02d}.asf", sorted(folder.glob("*.amc"))
