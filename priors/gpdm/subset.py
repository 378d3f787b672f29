"""The training frames a GPDM keeps from a large corpus.

A GPDM's training cost grows with the cube of its frames (exact) or linearly with a large constant (sparse), and
its tracking step with their number, so ``train --prior gpdm`` keeps at most ``max_frames`` frames. A corpus no
larger is used whole, as it is. A larger one is cut by this rule, drawn from the training's seeded generator:

1. every kept clip gives one stretch of consecutive frames (a GPDM learns the step from each frame to the next,
   so frames are never strided or scattered), of ``L = max(max_frames // clips, MIN_STRETCH)`` frames (a shorter
   clip gives all of its frames);
2. when the stretches of every clip do not fit, ``max_frames // L`` clips are drawn: the clips are grouped by
   their folder (a subject, or a corpus's folder of clips), the groups taken in turn, a random clip of each, so
   that every folder gives a clip before any gives a second;
3. each stretch starts at a random frame of its clip.

The choice (which clip, which frames) is recorded in the model file (:class:`Stretch`).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

#: Fewest frames of one clip's stretch: a second at 60 Hz, a stride or two of a walk.
MIN_STRETCH = 60


@dataclass(frozen=True)
class Stretch:
    """Frames ``start`` to ``stop`` (exclusive) of the training clip ``source``."""

    source: str
    start: int
    stop: int

    def as_dict(self) -> dict:
        return {"source": self.source, "start": self.start, "stop": self.stop}


def choose_frames(lengths: Sequence[int], sources: Sequence[str], max_frames: int,
                  rng: np.random.Generator) -> list[tuple[int, int, int]] | None:
    """The stretches ``(clip index, start, stop)`` a GPDM keeps of clips of ``lengths`` frames (named by
    ``sources``, whose folders group them), in clip order, by the rule of this module; None when the clips
    together have at most ``max_frames`` frames (all kept, and ``rng`` not drawn from)."""
    if sum(lengths) <= max_frames:
        return None
    n = len(lengths)
    stretch = max(max_frames // n, MIN_STRETCH)
    if stretch * n <= max_frames:
        chosen = list(range(n))
    else:
        groups: dict[str, list[int]] = {}
        for i, source in enumerate(sources):
            groups.setdefault(str(Path(source).parent), []).append(i)
        queues = [list(rng.permutation(members)) for members in groups.values()]
        chosen, want = [], max(max_frames // stretch, 1)
        while len(chosen) < want:
            for queue in queues:
                if queue and len(chosen) < want:
                    chosen.append(int(queue.pop()))
        chosen.sort()
    out = []
    for i in chosen:
        keep = min(stretch, lengths[i])
        start = int(rng.integers(lengths[i] - keep + 1))
        out.append((i, start, start + keep))
    return out
