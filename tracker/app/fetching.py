"""Getting the data an experiment file names: ``pose-tracker fetch`` and :func:`fetch`.

``fetch(["07_01", "16_15"], data_root="data")`` downloads CMU trials by subject and trial number
(:mod:`data_tools.motion.fetch`); ``fetch(experiment="exp.toml")`` downloads every CMU trial the file names into the
file's data root, the folder ``compare`` reads it from (``data_root`` given here, else the environment variable
``POSE_TRACKER_DATA_ROOT``, else the file's own ``data_root``, created when missing).
"""
from __future__ import annotations

import logging
import os
import re
import sys
from pathlib import Path
from typing import Any, Sequence

from data_tools.motion.cmu_trials import NOT_DOWNLOADABLE
from data_tools.motion.fetch import DEFAULT_TIMEOUT, CmuTrial, fetch_cmu, parse_trial
from tracker.app.experiment import DATA_ROOT_ENV
from tracker.core.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

log = logging.getLogger(__name__)

_CMU_PATH = re.compile(r"mocap/cmu/(\d+)/(\w+)\.(amc|asf)")


def _strings(value: Any):
    """Every string in a TOML document's value, depth first."""
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for v in value.values():
            yield from _strings(v)
    elif isinstance(value, list):
        for v in value:
            yield from _strings(v)


def experiment_needs(path: str | Path, data_root: str | Path | None = None) -> tuple[Path, list[str], list[str]]:
    """The data root of the experiment file ``path`` (see the module docstring; not required to exist), the CMU
    trials its data paths name (``mocap/cmu/07/07_01.amc`` -> ``"07_01"``) and the paths of the CMU files it names
    that no download can give (files named otherwise than CMU's trials), relative to the data root."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except FileNotFoundError:
        raise InputError("experiment file not found", path) from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"cannot read the experiment file ({exc})", path) from None
    declared = doc.get("data_root")
    env = os.environ.get(DATA_ROOT_ENV) or None
    if data_root is not None:
        root = Path(data_root).expanduser()
    elif declared is None:
        raise InputError("the file declares no data_root: its data paths are relative to the file, nothing to "
                         "fetch into", path)
    elif env is not None:
        root = Path(env).expanduser()
    elif isinstance(declared, str) and declared:
        root = Path(declared).expanduser()
        root = root if root.is_absolute() else path.resolve().parent / root
    else:
        raise InputError(f"data_root: expected a folder, got {declared!r}", path)
    trials: list[str] = []
    shared_only: list[str] = []
    for text in _strings(doc):
        for m in _CMU_PATH.finditer(text.replace("\\", "/")):
            subject, stem, kind = m.groups()
            if kind == "asf":
                continue  # every trial brings its subject's skeleton
            if stem in NOT_DOWNLOADABLE or not re.fullmatch(r"\d+_\d+", stem):
                shared_only.append(m.group(0))
            else:
                trials.append(stem)
    return root, list(dict.fromkeys(trials)), list(dict.fromkeys(shared_only))


def fetch(trials: Sequence[str] = (), *, experiment: str | Path | None = None,
          data_root: str | Path | None = None, mirror: str | None = None,
          timeout: float = DEFAULT_TIMEOUT) -> list[Path]:
    """Download CMU ``trials`` (``"07_01"``, ...) and those ``experiment`` names into ``data_root`` (for an
    experiment, default: its data root as ``compare`` finds it; otherwise ``data_root`` or the environment
    variable ``POSE_TRACKER_DATA_ROOT`` is required), from ``mirror`` (a base URL laid out as
    ``http://mocap.cs.cmu.edu/subjects``) or the CMU site. Files already there that pass their check are kept.
    Returns the paths of every file the trials need. An experiment file that names files no download can give
    (named otherwise than CMU's trials) is refused in one line once the rest is fetched, unless they are
    already in place."""
    chosen: list[str | CmuTrial] = [parse_trial(str(t)) for t in trials]
    missing: list[str] = []
    root: Path | None = None
    if experiment is not None:
        root, named, shared_only = experiment_needs(experiment, data_root)
        chosen += named
        missing = [p for p in shared_only if not (root / p).is_file()]
        log.info(f"{experiment}: {len(named)} CMU trial(s) named, into {root}")
    elif data_root is not None:
        root = Path(data_root).expanduser()
    elif os.environ.get(DATA_ROOT_ENV):
        root = Path(os.environ[DATA_ROOT_ENV]).expanduser()
    if root is None:
        raise InputError(f"say where the data goes: --data-root DIR (or {DATA_ROOT_ENV}), or --for EXPERIMENT.toml")
    if not chosen and not missing:
        raise InputError("nothing to fetch: name CMU trials (e.g. 07_01 16_15) or --for EXPERIMENT.toml")
    if root.exists() and not root.is_dir():
        raise InputError("data root is not a folder", root)
    placed = fetch_cmu(chosen, root, mirror=mirror, timeout=timeout)
    if missing:
        more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
        raise InputError(f"{missing[0]}{more} not found under {root}: named otherwise than the CMU database's "
                         f"trials, they cannot be downloaded; copy them from the shared data (docs/guide/data.md)",
                         experiment)
    return placed
