"""The default random-walk scale: the shipped subject-7 walks' per-dof RMS frame-to-frame change, derived once.

The zero- and constant-velocity priors step every pose number by noise of this scale (mm per frame for the
root's position, rad per frame for the angles; one number per dof, ``(40,)`` for the 15-cone model). By default
it is :func:`~tracker.core.representation.step_rms` of the shipped CMU walks 07_01 and 07_02
(:func:`data_tools.samples.sample_walks`) retargeted at the sequence's frame rate. Retargeting them takes
seconds, so the values for the usual rates, :data:`SHIPPED_RATES`, are derived once and shipped in
``walk_scale.json`` beside this module: exact float64 values (JSON keeps a float's shortest round-trip
decimal), so a run that reads them gives the numbers a run that retargets gives, bit for bit. Any other rate
is derived when asked for (:func:`derive_walk_scale`); so are the scales of the user's own training clips
(the API's ``train_mocap``), which never read this file.

The scale depends on the rate, and not as a plain ``1 / fps``: a step at 30 Hz is 1.1 to 2.0 times the 60 Hz
one, depending on the dof (smooth motion doubles, frame-to-frame jitter does not). So each rate is derived at
that rate and looked up exactly: a sequence at 29.97 Hz derives its own.

Regenerate the file after a change to retargeting, to the shipped walks or to :data:`SHIPPED_RATES` (the
tests compare every shipped value with a fresh derivation, exactly)::

    python -m tracker.app.walk_scale            # rewrites tracker/app/walk_scale.json
    python -m tracker.app.walk_scale --check    # exits 1 if the file differs from a fresh derivation
"""
from __future__ import annotations

import argparse
import json
import sys
from functools import lru_cache
from pathlib import Path
from typing import Iterable

import numpy as np

#: The shipped file: ``{"rates": {"60.0": [40 floats], ...}, ...}`` keyed by the frame rate (Hz) as ``repr``.
SHIPPED_FILE = Path(__file__).with_name("walk_scale.json")

#: Frame rates (Hz) whose scale is shipped: 60, the synthetic sequences' default; 25, 30 and 50, the rates
#: videos usually state (``pose-tracker capture`` tracks at the video's rate).
SHIPPED_RATES: tuple[float, ...] = (60.0, 50.0, 30.0, 25.0)


def derive_walk_scale(fps: float) -> np.ndarray:
    """The random-walk scale ``(D,)`` (mm or rad per frame) of the shipped subject-7 walks retargeted at
    ``fps`` Hz: their per-dof RMS frame-to-frame change. Takes seconds (it retargets both walks)."""
    from data_tools.motion.load import load_mocap
    from data_tools.motion.retarget import retarget
    from data_tools.samples import sample_walks
    from tracker.core.representation import step_rms

    asf, walks = sample_walks()
    return step_rms([retarget(load_mocap(w, asf), fps=fps).poses for w in walks])


@lru_cache(maxsize=1)
def _shipped_table() -> dict[float, tuple[float, ...]]:
    """The shipped file's scales by frame rate (Hz); empty when the file is missing."""
    if not SHIPPED_FILE.is_file():
        return {}
    rates = json.loads(SHIPPED_FILE.read_text(encoding="utf-8"))["rates"]
    return {float(rate): tuple(float(x) for x in values) for rate, values in rates.items()}


def shipped_walk_scale(fps: float) -> np.ndarray | None:
    """The shipped random-walk scale ``(D,)`` float64 for exactly ``fps`` Hz, equal to
    :func:`derive_walk_scale` ``(fps)``; None for a rate that is not shipped."""
    values = _shipped_table().get(float(fps))
    return None if values is None else np.array(values, dtype=np.float64)


def walk_scale(fps: float) -> np.ndarray:
    """The default random-walk scale ``(D,)`` at ``fps`` Hz: the shipped values where the rate is shipped,
    else derived from the walks (:func:`derive_walk_scale`)."""
    scale = shipped_walk_scale(fps)
    return derive_walk_scale(fps) if scale is None else scale


def shipped_content(rates: Iterable[float] = SHIPPED_RATES) -> dict:
    """What :data:`SHIPPED_FILE` holds, derived afresh for ``rates`` (Hz)."""
    from data_tools.samples import SAMPLES, sample_walks

    asf, walks = sample_walks()
    return {
        "description": "Default random-walk scale of the zero- and constant-velocity priors: per-dof RMS "
                       "frame-to-frame change of the shipped walks retargeted at each frame rate (Hz). "
                       "Written by python -m tracker.app.walk_scale; do not edit by hand.",
        "unit": "mm per frame (dofs 0-2), rad per frame (the rest)",
        "walks": [p.relative_to(SAMPLES).as_posix() for p in (asf, *walks)],
        "rates": {repr(float(fps)): [float(x) for x in derive_walk_scale(fps)] for fps in rates},
    }


def write_shipped(path: Path = SHIPPED_FILE, rates: Iterable[float] = SHIPPED_RATES) -> Path:
    """Derive the scales for ``rates`` (Hz) and write them to ``path`` (JSON); returns ``path``."""
    text = json.dumps(shipped_content(rates), indent=1) + "\n"
    path.write_text(text, encoding="utf-8")
    _shipped_table.cache_clear()
    return path


def main(argv: list[str] | None = None) -> int:
    """Regenerate (or with ``--check`` compare) the shipped file; returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m tracker.app.walk_scale", description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="compare the file with a fresh derivation")
    args = parser.parse_args(argv)
    if args.check:
        fresh = shipped_content()["rates"]
        shipped = json.loads(SHIPPED_FILE.read_text(encoding="utf-8"))["rates"] if SHIPPED_FILE.is_file() else {}
        if fresh != shipped:
            print(f"{SHIPPED_FILE} differs from a fresh derivation: regenerate it", file=sys.stderr)
            return 1
        print(f"{SHIPPED_FILE} matches a fresh derivation")
        return 0
    print(f"wrote {write_shipped()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
