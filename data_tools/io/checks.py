"""Sanity checks for values where they enter from files: plausible ranges, checked ``.npz`` arrays, body shapes.

Every reader uses these helpers, so a value out of range is refused the same
way everywhere: one :class:`InputError` naming the file (and line or key), the
value and the range expected. The ranges are deliberately generous: they
catch garbage (1e308, a string where a number goes), not unusual subjects.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from tracker.core.body import BodyShape
from tracker.core.errors import InputError

#: Positions and translations (mm): anything farther than 1 km from the origin is garbage.
MAX_POSITION_MM = 1e6
#: One body segment's length, radius or joint offset (mm).
MAX_BODY_MM = 5000.0
#: Cross-section scale of a body segment (dimensionless).
MAX_BODY_SCALE = 10.0
#: Mocap joint angles (degrees): many turns, for clips that accumulate the heading.
MAX_ANGLE_DEG = 1e5
#: Length units of mocap files (mm per file unit): 1 micrometre to 10 m.
MIN_MM_PER_UNIT, MAX_MM_PER_UNIT = 1e-3, 1e4
#: Frame rates (Hz): from a frame every 10 s (slower is no motion capture) to 100 kHz.
MIN_FPS, MAX_FPS = 0.1, 1e5
#: Cameras in one rig.
MAX_VIEWS = 64
#: Image width and height (pixels).
MAX_IMAGE_SIDE = 20000
#: Focal lengths and principal point coordinates (pixels).
MAX_FOCAL_PX = 1e6
MAX_PRINCIPAL_PX = 1e5
#: Skew (Bouguet's alpha_c) and lens distortion coefficients (dimensionless).
MAX_SKEW = 1.0
MAX_DISTORTION = 1e3
#: Largest array member of an ``.npz`` file read (bytes, uncompressed).
MAX_NPZ_MEMBER_BYTES = 1 << 30


def _range_text(lo: float, hi: float, positive: bool, unit: str) -> str:
    if positive:
        return "positive and finite" if np.isinf(hi) else f"positive and at most {hi:g}{unit}"
    if np.isinf(hi) and np.isinf(lo):
        return "finite"
    if lo == -hi:
        return f"finite and within ±{hi:g}{unit}"
    return f"finite and within [{lo:g}, {hi:g}]{unit}"


def check_range(values: Any, what: str, source: str | Path | None = None, *, hi: float = np.inf,
                lo: float | None = None, positive: bool = False, unit: str = "", line: int | None = None,
                row_lines: Sequence[int] | None = None, scale: float = 1.0) -> np.ndarray:
    """``values * scale`` as a float array, refused unless every entry is finite and in range.

    The range is ``[lo, hi]`` (``lo`` defaults to ``-hi``), or ``(0, hi]`` when
    ``positive``; ``scale`` converts the values to the range's unit (file
    units to mm, say) without overflow warnings. ``row_lines[i]`` is the file
    line of row ``i`` (for tables); otherwise ``line`` is reported. The
    message names ``what``, the first bad entry's index (for 2-d and larger
    arrays), its value and the range.
    """
    raw = np.asarray(values, dtype=float)
    with np.errstate(over="ignore"):
        v = raw * scale if scale != 1.0 else raw
    lo = (0.0 if positive else -hi) if lo is None else lo
    ok = (v <= hi) & ((v > lo) if positive else (v >= lo))  # False for NaN
    if np.isinf(hi) or np.isinf(lo):
        ok &= np.isfinite(v)
    if ok.all():
        return v
    idx = tuple(int(i) for i in np.argwhere(~ok)[0]) if v.ndim else ()
    if row_lines is not None and idx:
        line = row_lines[idx[0]]
    where = f"[{', '.join(map(str, idx))}]" if v.ndim >= 2 else ""
    expected = _range_text(lo, hi, positive, unit)
    if not np.isfinite(raw[idx]):
        raise InputError(f"{what}{where}: NaN or infinite value (expected {expected})", source, line)
    shown = f"{v[idx]:.6g}" if np.isfinite(v[idx]) else f"{raw[idx]:.6g} x {scale:g}"
    raise InputError(f"{what}{where} = {shown} is outside the plausible range (expected {expected})", source, line)


def real_number(value: Any, what: str, source: str | Path | None = None, *, hi: float = np.inf,
                lo: float | None = None, positive: bool = False, unit: str = "") -> float:
    """A JSON-style scalar that must be a real number (not a string, list or bool) within range."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{what} must be a number, got {_short(value)}", source)
    try:
        value = float(value)
    except OverflowError:  # an integer beyond the float range
        value = float("inf")
    return float(check_range(value, what, source, hi=hi, lo=lo, positive=positive, unit=unit))


def number_array(value: Any, what: str, source: str | Path | None = None) -> np.ndarray:
    """A JSON-style nested list of numbers as a float array; text, ragged lists and huge integers are refused."""
    if isinstance(value, (str, bytes, dict)):
        raise InputError(f"{what} must be numbers, got {_short(value)}", source)
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{what} must be numbers (a list or table of them), got {_short(value)}", source) from None


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# ---------------------------------------------------------------------------
# .npz files
# ---------------------------------------------------------------------------

def load_npz(path: str | Path, what: str, required: Sequence[str]) -> dict[str, np.ndarray]:
    """Every array of an ``.npz`` file, loaded without pickles.

    Missing, empty, truncated, non-zip and non-``.npz`` files, object arrays,
    members over :data:`MAX_NPZ_MEMBER_BYTES` and missing ``required`` keys raise
    :class:`InputError` naming the file.
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:
            magic = f.read(6)
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror or exc}", path) from None
    if magic.startswith(b"\x93NUMPY"):
        raise InputError(f"{what} is a single .npy array, not an .npz archive of named arrays", path)
    if not magic.startswith(b"PK"):  # np.load would try other formats (pickles, text) on anything else
        raise InputError(f"cannot read {what}: not an .npz file (an .npz is a zip archive of .npy arrays)", path)
    try:
        with open(path, "rb") as f, np.load(f, allow_pickle=False) as z:
            big = [i.filename for i in z.zip.infolist() if i.file_size > MAX_NPZ_MEMBER_BYTES]
            if big:
                raise InputError(f"{what} member {big[0]} is larger than {MAX_NPZ_MEMBER_BYTES >> 20} MiB", path)
            arrays = {k: z[k] for k in z.files}
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 -- zipfile, zlib and numpy.lib.format fail in many undocumented ways
        reason = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {what}: not an intact .npz file ({reason})", path) from None
    missing = [k for k in required if k not in arrays]
    if missing:
        raise InputError(f"{what} lacks {', '.join(missing)} (has {', '.join(sorted(arrays)) or 'nothing'})", path)
    return arrays


def checked_array(arrays: Mapping[str, np.ndarray], key: str, path: str | Path, shape: Sequence[int | str],
                  dims: dict[str, int] | None = None, *, hi: float, lo: float | None = None,
                  positive: bool = False, unit: str = "") -> np.ndarray:
    """``arrays[key]`` as float64, refused unless real-valued, of ``shape`` and in range (see :func:`check_range`).

    ``shape`` entries are sizes or names; a name takes its size from ``dims``
    (shared between calls, e.g. the frame count ``"T"``) or, on first use, sets it.
    """
    a = arrays[key]
    if a.dtype.kind not in "iuf":
        kind = {"U": "text", "S": "bytes", "c": "complex numbers", "b": "booleans"}.get(a.dtype.kind, str(a.dtype))
        raise InputError(f"{key} must be real numbers, got {kind}", path)
    dims = {} if dims is None else dims
    expected = tuple(dims.get(s, -1) if isinstance(s, str) else s for s in shape)
    text = " x ".join(f"{s} ({dims[s]})" if isinstance(s, str) and s in dims else str(s) for s in shape)
    named_empty = any(isinstance(s, str) and n == 0 for s, n in zip(shape, a.shape))
    if a.ndim != len(shape) or named_empty or any(e >= 0 and e != n for e, n in zip(expected, a.shape)):
        at_least = ", each named size at least 1" if any(isinstance(s, str) for s in shape) else ""
        raise InputError(f"{key} must have shape {text or '() (a single number)'}{at_least}, got {a.shape}", path)
    for s, n in zip(shape, a.shape):
        if isinstance(s, str):
            dims.setdefault(s, n)
    return check_range(a, key, path, hi=hi, lo=lo, positive=positive, unit=unit)


def checked_motion(arrays: Mapping[str, np.ndarray], path: str | Path, n_dofs: int,
                   marker_keys: Sequence[str] = ("markers",)) -> tuple[np.ndarray, list[np.ndarray], float]:
    """The poses ``T x n_dofs`` (mm and rad), markers ``T x 15 x 3`` (mm, one array per key) and fps of an archive.

    Shared by the ground truth of a sequence and converted clips; every value
    is checked for type, shape (``T >= 1``) and range.
    """
    dims: dict[str, int] = {}
    poses = checked_array(arrays, "poses", path, ("T", n_dofs), dims, hi=MAX_POSITION_MM, unit=" mm or rad")
    markers = [checked_array(arrays, k, path, ("T", 15, 3), dims, hi=MAX_POSITION_MM, unit=" mm")
               for k in marker_keys]
    fps = float(checked_array(arrays, "fps", path, (), hi=MAX_FPS, positive=True, unit=" Hz"))
    return poses, markers, fps


def checked_text(arrays: Mapping[str, np.ndarray], key: str, path: str | Path, ndim: int = 0) -> str | list[str]:
    """``arrays[key]`` as a string (``ndim`` 0) or a list of strings (``ndim`` 1); anything else is refused."""
    a = arrays[key]
    if a.dtype.kind != "U" or a.ndim != ndim:
        wanted = "a string" if ndim == 0 else "a list of strings"
        raise InputError(f"{key} must be {wanted}, got {a.dtype} of shape {a.shape}", path)
    return str(a) if ndim == 0 else [str(s) for s in a]


# ---------------------------------------------------------------------------
# Body shapes (meta.json, converted clips)
# ---------------------------------------------------------------------------

_SHAPE_TABLES = {"lengths": MAX_BODY_MM, "radius_proximal": MAX_BODY_MM, "radius_distal": MAX_BODY_MM,
                 "depth_scale": MAX_BODY_SCALE}
_SHAPE_OFFSETS = ("left_hip_offset", "right_hip_offset", "left_shoulder_offset", "right_shoulder_offset",
                  "abdomen_offset")


def body_shape(d: Any, source: str | Path | None) -> BodyShape:
    """A :class:`BodyShape` from its JSON dictionary, refusing wrong types and implausible sizes first."""
    if not isinstance(d, dict):
        raise InputError(f"body shape must be a JSON object, got {_short(d)}", source)
    for table, hi in _SHAPE_TABLES.items():
        values = d.get(table)
        if not isinstance(values, dict):
            raise InputError(f"body shape {table} must be an object of segment: number, got {_short(values)}",
                             source)
        for name, v in values.items():
            real_number(v, f"body shape {table}[{name}]", source, hi=hi, positive=True,
                        unit="" if table == "depth_scale" else " mm")
    for name in _SHAPE_OFFSETS:
        off = d.get(name, [0.0, 0.0, 0.0] if name == "abdomen_offset" else None)
        if not isinstance(off, list) or len(off) != 3:
            raise InputError(f"body shape {name} must be a list of 3 numbers (mm), got {_short(off)}", source)
        for k, v in enumerate(off):
            real_number(v, f"body shape {name}[{k}]", source, hi=MAX_BODY_MM, unit=" mm")
    real_number(d.get("foot_pitch", 0.3), "body shape foot_pitch", source, hi=np.pi / 2, unit=" rad")
    return BodyShape.from_dict(d, str(source) if source is not None else None)
