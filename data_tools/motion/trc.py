"""TRC marker files (OpenSim's and Pose2Sim's text format): read and write.

A TRC file is five header lines (``PathFileType``, the names and values of ``DataRate CameraRate NumFrames
NumMarkers Units ...``, ``Frame# Time`` and the marker names, ``X1 Y1 Z1 ...``) and then one tab-separated row
per frame: frame number, time (s), then x y z of every marker; an empty cell is a missing value (NaN here).

World frames: this toolkit's is z up, millimetres, the body facing +x in its rest pose. OpenSim's and
Pose2Sim's TRC files are y up, in the file's ``Units`` (``m`` or ``mm``). Pose2Sim writes its z-up world's
``(x, y, z)`` as the TRC's ``(Z, X, Y)``, so the TRC's ``(X, Y, Z)`` is our ``(y, z, x)``; both functions use that
mapping (a proper rotation: nothing is mirrored), so a file this module writes lies in the same place as the
calibrated cameras for Pose2Sim, and a Pose2Sim reconstruction read here lies in its calibration's world.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from data_tools.io.checks import MAX_FPS, MAX_POSITION_MM, check_range
from data_tools.io.textfiles import read_lines
from tracker.core.errors import InputError

#: Our axes in TRC columns: TRC (X, Y, Z) = ours (y, z, x).
_TO_TRC = [1, 2, 0]
_FROM_TRC = [2, 0, 1]
_UNITS = {"m": 1000.0, "mm": 1.0, "cm": 10.0}


@dataclass
class TrcData:
    """Marker trajectories: ``points`` ``T x N x 3`` in this toolkit's world (z up, mm; NaN where missing),
    ``names`` (N), ``fps`` (Hz), ``frame_numbers`` (T, as the file numbers them)."""

    names: list[str]
    points: np.ndarray
    fps: float
    frame_numbers: np.ndarray


def read_trc(path: str | Path) -> TrcData:
    """Read a TRC file (module docstring) into our world frame and millimetres."""
    path = Path(path)
    lines = read_lines(path, "TRC file")
    if len(lines) < 6:
        raise InputError(f"a TRC file has 5 header lines and then frames; this one has {len(lines)} lines", path)
    keys, values = lines[1].split("\t"), lines[2].split("\t")
    header = {k.strip(): v.strip() for k, v in zip(keys, values)}
    for key in ("DataRate", "NumMarkers", "Units"):
        if key not in header:
            raise InputError(f"line 2 lacks {key} (expected DataRate CameraRate NumFrames NumMarkers Units ...)",
                             path, 2)
    try:
        fps, n_markers = float(header["DataRate"]), int(header["NumMarkers"])
    except ValueError:
        raise InputError("DataRate and NumMarkers must be numbers", path, 3) from None
    if not 0 < fps <= MAX_FPS:
        raise InputError(f"DataRate must be in (0, {MAX_FPS:g}] Hz, got {header['DataRate']}", path, 3)
    unit = header["Units"].lower()
    if unit not in _UNITS:
        raise InputError(f"Units must be m, cm or mm, got {header['Units']!r}", path, 3)
    names = [n.strip() for n in lines[3].split("\t")[2:] if n.strip()]
    if len(names) != n_markers:
        raise InputError(f"NumMarkers says {n_markers} but line 4 names {len(names)} markers", path, 4)
    rows, numbers, row_lines = [], [], []
    for i, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        cells = line.rstrip("\n").split("\t")
        if len(cells) < 2 + 3 * n_markers:
            cells += [""] * (2 + 3 * n_markers - len(cells))
        try:
            numbers.append(int(float(cells[0])))
            rows.append([float(c) if c.strip() else np.nan for c in cells[2:2 + 3 * n_markers]])
        except ValueError:
            raise InputError("a frame row must hold numbers (or empty cells for missing values)", path, i) from None
        row_lines.append(i)
    if not rows:
        raise InputError("no frames", path)
    data = np.array(rows).reshape(len(rows), n_markers, 3) * _UNITS[unit]
    finite = np.where(np.isfinite(data), data, 0.0)
    check_range(finite, "marker coordinates", path, hi=MAX_POSITION_MM, unit=" mm", row_lines=row_lines)
    return TrcData(names, data[..., _FROM_TRC], fps, np.array(numbers))


def write_trc(path: str | Path, names: Sequence[str], points: np.ndarray, fps: float, unit: str = "m") -> None:
    """Write ``points`` ``T x N x 3`` (our world: z up, mm) as a y-up TRC file in ``unit`` (m or mm)."""
    points = np.asarray(points, float)
    if points.ndim != 3 or points.shape[1:] != (len(names), 3):
        raise InputError(f"points must be T x {len(names)} x 3, got shape {points.shape}")
    scale = _UNITS[unit]
    data = points[..., _TO_TRC] / scale
    T, N = data.shape[:2]
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{Path(path).name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
             f"{fps:g}\t{fps:g}\t{T}\t{N}\t{unit}\t{fps:g}\t1\t{T}",
             "Frame#\tTime\t" + "\t\t\t".join(names) + "\t\t",
             "\t\t" + "\t".join(f"X{i + 1}\tY{i + 1}\tZ{i + 1}" for i in range(N))]
    for t in range(T):
        cells = ["" if not np.isfinite(v) else f"{v:.6f}" for v in data[t].ravel()]
        lines.append(f"{t + 1}\t{t / fps:.6f}\t" + "\t".join(cells))
    Path(path).write_text("\n".join(lines) + "\n")
