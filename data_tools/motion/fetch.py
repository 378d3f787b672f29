"""Download CMU motion capture trials into a data root, checked by their content (``pose-tracker fetch``).

Files land where the shipped experiment files look for them: ``<root>/mocap/cmu/07/07_01.amc`` beside the
subject's skeleton ``<root>/mocap/cmu/07/07.asf``. They come from the CMU Graphics Lab Motion Capture Database
(``http://mocap.cs.cmu.edu/subjects/07/07_01.amc``; subject folders have at least two digits, trials two), or
from a mirror with the same layout under another base URL.

Each file is written under a temporary name (``07_01.amc.part``), parsed (the skeleton: CMU's bones and, for a
recorded subject, its bone lengths; the motion: against its skeleton, and, for a recorded trial, its number of
frames, :mod:`data_tools.motion.cmu_trials`) and only then renamed; a file already in place that passes the same check
is not downloaded again, so a second run after an interrupted one fetches only what is missing. Every failure
is one :class:`InputError`: naming the URL when the site is unreachable, a file is missing there or does not
pass its check, naming the path when a folder or file cannot be written (a file in a folder's place, no
permission, a full disk). A failed file leaves nothing behind, not even the folders made for it.
"""
from __future__ import annotations

import http.client
import logging
import os
import re
import socket
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from data_tools.motion.asf_amc import read_amc, read_asf
from data_tools.motion.cmu_trials import CMU_BONES, NOT_DOWNLOADABLE, SKELETON_LENGTHS, TRIAL_FRAMES
from tracker.core.errors import InputError

log = logging.getLogger(__name__)

#: The CMU database's folder of subjects.
CMU_URL = "http://mocap.cs.cmu.edu/subjects"
#: Where, under a data root, the CMU files go (as the shipped experiment files name them).
CMU_FOLDER = Path("mocap") / "cmu"
#: Relative tolerance on a skeleton's summed bone lengths (the copies differ only in formatting).
LENGTH_TOLERANCE = 1e-3
#: Seconds to wait for the server before giving up on a file.
DEFAULT_TIMEOUT = 30.0
_TRIAL = re.compile(r"(\d{1,3})_(\d{1,2})")


@dataclass(frozen=True)
class CmuTrial:
    """One trial of the CMU database: ``subject`` as the site names its folder (``"07"``, ``"131"``) and
    ``trial`` as two digits (``"01"``)."""

    subject: str
    trial: str

    @property
    def name(self) -> str:
        return f"{self.subject}_{self.trial}"

    def files(self) -> tuple[str, str]:
        """The skeleton's and the motion's paths below the subjects folder: ``07/07.asf``, ``07/07_01.amc``."""
        return f"{self.subject}/{self.subject}.asf", f"{self.subject}/{self.name}.amc"


def parse_trial(text: str) -> CmuTrial:
    """``"07_01"`` (or ``"7_1"``, or a file name ``07_01.amc``) as a :class:`CmuTrial`; anything else is one
    :class:`InputError`, which for a file the package knows by another name says what it may be."""
    stem = Path(text).name
    stem = stem[:-4] if stem.lower().endswith(".amc") else stem
    if stem in NOT_DOWNLOADABLE:
        raise InputError(f"{stem} is not one of the CMU database's trial names and cannot be downloaded (it may be "
                         f"{NOT_DOWNLOADABLE[stem]}); it is read from a copy of the shared data "
                         f"(docs/guide/data.md)")
    m = _TRIAL.fullmatch(stem)
    if not m or int(m.group(1)) == 0 or int(m.group(2)) == 0:
        raise InputError(f"{text!r} is not a CMU trial: expected SUBJECT_TRIAL, e.g. 07_01 or 16_15")
    return CmuTrial(f"{int(m.group(1)):02d}", f"{int(m.group(2)):02d}")


def check_skeleton(path: Path, subject: str, source: str) -> None:
    """``path`` parses as an ASF with CMU's bones and, for a recorded ``subject``, that subject's bone lengths;
    otherwise one :class:`InputError` naming ``source`` (the URL, or the file)."""
    try:
        skeleton = read_asf(path)
    except InputError as exc:
        raise InputError(f"not a readable ASF skeleton ({exc.reason})", source) from None
    bones = set(skeleton.bones)
    if bones != set(CMU_BONES):
        raise InputError(f"not a CMU skeleton: its bones differ from CMU's ({len(bones)} bones, "
                         f"{len(bones - set(CMU_BONES))} unknown)", source)
    expected = SKELETON_LENGTHS.get(subject)
    total = sum(b.length for b in skeleton.bones.values())
    if expected is not None and abs(total - expected) > LENGTH_TOLERANCE * expected:
        raise InputError(f"not subject {subject}'s skeleton: its bone lengths sum to {total:.4f} units, the "
                         f"recorded subject's to {expected:.4f}", source)


def check_motion(path: Path, skeleton: Path, name: str, source: str) -> int:
    """``path`` parses as an AMC on the ASF ``skeleton`` and, for a recorded trial ``name``, has its number of
    frames; returns the frames. Otherwise one :class:`InputError` naming ``source``."""
    try:
        frames = len(read_amc(path, read_asf(skeleton))["root"])
    except InputError as exc:
        raise InputError(f"not a readable AMC motion of {skeleton.name} ({exc.reason})", source) from None
    expected = TRIAL_FRAMES.get(name)
    if expected is not None and frames != expected:
        raise InputError(f"{frames} frames where trial {name} has {expected} (an incomplete download or another "
                         f"file)", source)
    return frames


def _download(url: str, part: Path, timeout: float) -> None:
    """The body of ``url`` (a file of a few MB) into ``part``; the site unreachable or the file not there is one line
    naming the URL, a file that cannot be written (no permission, a full disk) one line naming ``part``."""
    try:
        with urllib.request.urlopen(url, timeout=timeout) as response:
            body = bytearray()
            while chunk := response.read(1 << 16):  # a body cut short is refused by its check
                body += chunk
    except urllib.error.HTTPError as exc:
        raise InputError(f"the server answered HTTP {exc.code} ({exc.reason})", url) from None
    except urllib.error.URLError as exc:
        raise InputError(f"cannot reach the server ({exc.reason}); offline? --mirror URL names another copy",
                         url) from None
    except (socket.timeout, TimeoutError, ConnectionError, http.client.HTTPException) as exc:
        raise InputError(f"the download failed ({exc or type(exc).__name__}); rerun to continue", url) from None
    try:
        part.write_bytes(body)
    except OSError as exc:
        raise InputError(f"cannot write the download ({exc.strerror or exc})", part) from None


def _make_folder(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; returns the folders created, deepest first. A folder that cannot
    be created (a file in its place or above it, no permission) is one :class:`InputError` naming it."""
    created = []
    missing = folder
    while not missing.exists() and missing != missing.parent:
        created.append(missing)
        missing = missing.parent
    if not missing.is_dir():
        raise InputError(f"not a folder, so {folder} cannot be created", missing)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder ({exc.strerror or exc})", exc.filename or folder) from None
    return created


def _fetch_file(url: str, dest: Path, check, timeout: float) -> bool:
    """``dest`` from ``url`` unless a copy that passes ``check(path, source)`` is there; True when downloaded.
    The download goes to ``dest.part`` and is renamed only once checked; a refused one is removed, with the
    folders made for it."""
    if dest.is_file():
        try:
            check(dest, str(dest))
            log.debug(f"{dest}: already there, checked")
            return False
        except InputError as exc:
            log.warning(f"{exc}; downloading it again")
    created = _make_folder(dest.parent)
    part = dest.with_name(dest.name + ".part")
    try:
        _download(url, part, timeout)
        check(part, url)
        try:
            os.replace(part, dest)
        except OSError as exc:
            raise InputError(f"cannot put the download in place ({exc.strerror or exc})", dest) from None
    except BaseException:
        try:
            part.unlink(missing_ok=True)
        except OSError:
            pass  # nothing was written there (a folder in its place)
        for folder in created:  # deepest first; one that holds something stays
            try:
                folder.rmdir()
            except OSError:
                break
        raise
    log.info(f"{url} -> {dest}")
    return True


def fetch_cmu(trials: Iterable[str | CmuTrial], data_root: str | Path, mirror: str | None = None,
              timeout: float = DEFAULT_TIMEOUT) -> list[Path]:
    """Download CMU ``trials`` (``"07_01"``, ...) and their subjects' skeletons into ``data_root``
    (``mocap/cmu/07/07_01.amc``, ``mocap/cmu/07/07.asf``), from ``mirror`` (a base URL laid out as the
    database's ``subjects`` folder) or the CMU site; returns every file's path, fetched or already there.

    Files already in place that pass their check are kept; see the module docstring. Every failure is one
    :class:`InputError` naming the URL, the trial or the path; what was fetched before it stays."""
    if not isinstance(timeout, (int, float)) or not timeout > 0:
        raise InputError(f"timeout: expected a positive number of seconds, got {timeout!r}")
    parsed = [t if isinstance(t, CmuTrial) else parse_trial(str(t)) for t in trials]
    base = (mirror or CMU_URL).rstrip("/")
    if not re.match(r"(?i)(https?|file)://", base):
        raise InputError(f"--mirror: expected an http://, https:// or file:// URL, got {mirror!r}")
    folder = Path(data_root).expanduser() / CMU_FOLDER
    placed: list[Path] = []
    fetched = 0
    for t in dict.fromkeys(parsed):  # in order, once each
        asf_rel, amc_rel = t.files()
        asf = folder / asf_rel
        if asf not in placed:
            fetched += _fetch_file(f"{base}/{asf_rel}", asf,
                                   lambda p, src, s=t.subject: check_skeleton(p, s, src), timeout)
            placed.append(asf)
        amc = folder / amc_rel
        fetched += _fetch_file(f"{base}/{amc_rel}", amc,
                               lambda p, src, a=asf, n=t.name: check_motion(p, a, n, src), timeout)
        placed.append(amc)
    log.info(f"{fetched} file(s) downloaded, {len(placed) - fetched} already there, under {folder}")
    return placed
