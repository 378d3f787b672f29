"""A mocap corpus: labels per clip from a pattern over file names or from a sidecar file, and a survey of what
the corpus holds.

The files themselves come from :func:`~data_tools.motion.load.expand_mocap` (files, folders searched recursively, glob
patterns; sorted, each once).

**Labels** (:class:`LabelSource`). ``dataset-2_{content}_{style}_{take}`` is a pattern over the file name
without its suffix: each ``{key}`` matches one or more characters (the shortest that makes the whole name
match; a key used twice must match the same text), ``{}`` matches without recording, other characters match
themselves; with a ``/`` the pattern matches the last folders of the path too (``{subject}/{subject}_{trial}``).
A sidecar file (``.csv``, ``.toml`` or ``.json``) maps files to labels: CSV with a header row whose first column
holds the files and every other column a key; TOML or JSON mapping each file to a table of ``key = label`` (or
to one label, key ``label``). A sidecar's file names are paths relative to the sidecar's folder, or bare file
names, with or without the suffix. ``#KEY`` after a pattern or a sidecar picks the key a training uses as its
label (``#content,style``: the two joined by ``.``, e.g. ``walk.elderly``); without it the source must have
exactly one key.
"""
from __future__ import annotations

import csv
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Sequence

from tracker.core.errors import InputError

#: Sidecar label files, by suffix.
SIDECAR_SUFFIXES = (".csv", ".toml", ".json")
#: What a label value may hold (the FCRBM's labels: letters, digits, '_', '-', '.').
LABEL_VALUE = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclass(frozen=True)
class LabelSource:
    """Labels per clip: from a name ``pattern`` (see the module docstring) or a ``sidecar`` file's ``table``
    (file -> key -> label); ``keys`` the keys a training's label is built from (None: the only key)."""

    text: str
    pattern: re.Pattern | None = None
    names: tuple[str, ...] = ()
    depth: int = 1
    sidecar: Path | None = None
    table: dict = field(default_factory=dict)
    keys: tuple[str, ...] | None = None

    def labels_of(self, path: str | Path) -> dict[str, str]:
        """Every key's label of the clip ``path``; an :class:`InputError` naming the file when the pattern does
        not match it or the sidecar has no entry for it."""
        path = Path(path)
        if self.pattern is not None:
            name = "/".join(path.with_suffix("").parts[-self.depth:])
            m = self.pattern.fullmatch(name)
            if m is None:
                raise InputError(f"the name does not match the labels pattern {self.text!r}", path)
            return {k: m.group(k) for k in self.names}
        entry = None
        for key in self._lookups(path):
            if key in self.table:
                entry = self.table[key]
                break
        if entry is None:
            raise InputError(f"no labels for this file in {self.sidecar}", path)
        return dict(entry)

    def _lookups(self, path: Path) -> list[str]:
        keys = []
        try:
            rel = path.resolve().relative_to(self.sidecar.parent.resolve())
            keys += [rel.as_posix(), rel.with_suffix("").as_posix()]
        except ValueError:
            pass
        return keys + [path.name, path.stem]

    def training_keys(self) -> tuple[str, ...]:
        """The keys a training label is built from: those after ``#``, else the source's only key; an
        :class:`InputError` when the source has several and none is chosen."""
        if self.keys is not None:
            return self.keys
        names = self.names if self.pattern is not None else tuple(dict.fromkeys(k for e in self.table.values()
                                                                                  for k in e))
        if len(names) != 1:
            raise InputError(f"labels {self.text!r} give several keys ({', '.join(names)}): choose the training "
                             f"label with #KEY, e.g. {self.text}#{names[-1] if names else 'style'}")
        return names

    def label_of(self, path: str | Path) -> str:
        """The training label of the clip ``path``: the value of the chosen key (keys joined by ``.``)."""
        keys = self.training_keys()
        labels = self.labels_of(path)
        missing = [k for k in keys if k not in labels]
        if missing:
            raise InputError(f"labels: no key {missing[0]!r} (the keys: {', '.join(labels) or 'none'})", path)
        return ".".join(labels[k] for k in keys)

    def training_labels(self, sources: Sequence[str | Path], unlabelled: str | None = None) -> list[str]:
        """One training label per clip of ``sources``, in their order; a clip the source gives no label (its name
        does not match, the sidecar lacks it or its key) is refused, or labelled ``unlabelled`` when given."""
        labels = []
        for s in sources:
            try:
                labels.append(self.label_of(s))
            except InputError:
                if unlabelled is None:
                    raise
                labels.append(unlabelled)
        return labels


def is_label_source(text: object) -> bool:
    """Whether a ``labels`` value names labels by pattern or sidecar file (rather than listing them in clip
    order): it holds a ``{key}`` field, or (without its ``#KEY``) names a ``.csv``, ``.toml`` or ``.json``
    file."""
    if not isinstance(text, (str, Path)):
        return False
    text = str(text)
    head = text.rsplit("#", 1)[0] if "#" in text else text
    return "{" in head or Path(head).suffix.lower() in SIDECAR_SUFFIXES


def _compile(pattern: str) -> tuple[re.Pattern, tuple[str, ...]]:
    if any("{" in piece or "}" in piece for piece in re.split(r"\{[^{}]*\}", pattern)):
        raise InputError(f"labels pattern {pattern!r}: unbalanced braces")
    regex, names, pos = [], [], 0
    for m in re.finditer(r"\{([^{}]*)\}", pattern):
        regex.append(re.escape(pattern[pos:m.start()]))
        key = m.group(1).strip()
        if not key:
            regex.append(r"[^/]+?")
        elif not key.isidentifier():
            raise InputError(f"labels pattern {pattern!r}: {{{key}}} is not a key (letters, digits, '_')")
        elif key in names:
            regex.append(f"(?P={key})")
        else:
            names.append(key)
            regex.append(f"(?P<{key}>[^/]+?)")
        pos = m.end()
    regex.append(re.escape(pattern[pos:]))
    return re.compile("".join(regex)), tuple(names)


def _check_value(value: object, key: str, where: str | Path) -> str:
    text = str(value).strip()
    if not LABEL_VALUE.match(text):
        raise InputError(f"label {key} = {text!r} is not a label (letters, digits, '_', '-', '.')", where)
    return text


def _read_sidecar(path: Path) -> dict[str, dict[str, str]]:
    if not path.is_file():
        raise InputError("no such labels file", path)
    suffix = path.suffix.lower()
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the labels file ({exc})", path) from None
    table: dict[str, dict[str, str]] = {}
    if suffix == ".csv":
        rows = [r for r in csv.reader(text.splitlines()) if any(c.strip() for c in r)]
        if len(rows) < 2 or len(rows[0]) < 2:
            raise InputError("a labels CSV needs a header row (file, then one column per key) and a row per "
                             "file", path)
        header = [h.strip() for h in rows[0]]
        for i, row in enumerate(rows[1:], start=2):
            if len(row) != len(header):
                raise InputError(f"line {i}: {len(row)} column(s), the header has {len(header)}", path)
            table[row[0].strip()] = {k: _check_value(v, k, f"{path}:{i}") for k, v in zip(header[1:], row[1:])}
        return table
    try:
        if suffix == ".json":
            doc = json.loads(text)
        else:
            try:
                import tomllib
            except ModuleNotFoundError:  # Python < 3.11
                import tomli as tomllib
            doc = tomllib.loads(text)
    except ValueError as exc:
        raise InputError(f"not valid {suffix[1:].upper()} ({exc})", path) from None
    if not isinstance(doc, dict) or not doc:
        raise InputError("a labels file maps each file to its labels, e.g. {\"a.bvh\": {\"style\": \"walk\"}}",
                         path)
    for name, entry in doc.items():
        entry = {"label": entry} if not isinstance(entry, dict) else entry
        if not entry:
            raise InputError(f"{name}: no labels", path)
        table[str(name)] = {str(k): _check_value(v, str(k), path) for k, v in entry.items()}
    return table


def label_source(text: str | Path, base: Path | None = None) -> LabelSource:
    """The :class:`LabelSource` a ``labels`` value names (a pattern or a sidecar file, then an optional
    ``#KEY``); a sidecar path relative to ``base`` (None: the working folder)."""
    text = str(text)
    head, _, chosen = text.rpartition("#") if "#" in text else (text, "", "")
    keys = tuple(k.strip() for k in chosen.split(",")) if chosen else None
    if keys is not None and not all(k.isidentifier() for k in keys):
        raise InputError(f"labels {text!r}: #{chosen} does not name keys (#style or #content,style)")
    if "{" in head:
        pattern, names = _compile(head)
        if not names:
            raise InputError(f"labels pattern {head!r} names no key: write {{key}} where a label stands")
        if keys is not None and (missing := [k for k in keys if k not in names]):
            raise InputError(f"labels pattern {head!r} has no key {missing[0]!r} (its keys: {', '.join(names)})")
        return LabelSource(text, pattern, names, head.count("/") + 1, keys=keys)
    path = Path(head).expanduser()
    if base is not None and not path.is_absolute():
        path = base / path
    return LabelSource(text, sidecar=path, table=_read_sidecar(path), keys=keys)


# -- the survey ---------------------------------------------------------------------------------------------

@dataclass
class CorpusEntry:
    """One file of a corpus as read: ``frames`` at ``fps`` Hz, its skeleton's ``naming`` convention, length
    ``unit`` and ``up`` axis, its ``labels`` (key -> label), and ``refused`` (the reason) when it cannot be
    read."""

    path: str
    format: str = ""
    frames: int = 0
    fps: float = 0.0
    naming: str = ""
    unit: str = ""
    up: str = ""
    labels: dict[str, str] = field(default_factory=dict)
    refused: str | None = None

    @property
    def seconds(self) -> float:
        return self.frames / self.fps if self.fps else 0.0

    def as_dict(self) -> dict:
        d = {"file": self.path, "format": self.format, "frames": self.frames, "fps": self.fps,
             "seconds": round(self.seconds, 3), "naming": self.naming, "unit": self.unit, "up": self.up,
             "labels": self.labels}
        return d if self.refused is None else {"file": self.path, "refused": self.refused}


def survey(items: str | Path | Iterable[str | Path], labels: str | Path | None = None) -> list[CorpusEntry]:
    """Every mocap file ``items`` name (:func:`~data_tools.motion.load.expand_mocap`) read as a training reads it (its
    reader, the naming convention of its points), with its labels from ``labels`` (:func:`label_source`): one
    entry per file, a file that cannot be read or labelled refused with its reason, never stopping at the
    first. An item that names nothing, or a bad ``labels``, is an :class:`InputError`."""
    from data_tools.motion.load import expand_mocap, load_mocap, reader_for

    files = expand_mocap(items)
    source = None if labels is None else label_source(labels)
    out = []
    for f in files:
        entry = CorpusEntry(str(f))
        try:
            entry.format = reader_for(f).name
            clip = load_mocap(f)
            entry.naming = clip.point_plan().naming
            entry.frames, entry.fps, entry.unit, entry.up = clip.n_frames, float(clip.fps), clip.unit, clip.up
            if clip.n_frames < 1:
                raise InputError("the clip has no frames", f)
            if source is not None:
                entry.labels = source.labels_of(f)
        except InputError as exc:
            entry.refused = exc.reason
        out.append(entry)
    return out


@dataclass(frozen=True)
class SurveyTotals:
    """What a survey found, summed: the ``clips`` read, their ``frames`` and ``seconds``, how many clips at each
    frame ``rates`` (Hz -> count, by rate), and how many files were ``refused``."""

    clips: int
    frames: int
    seconds: float
    rates: dict[float, int]
    refused: int

    def as_dict(self) -> dict:
        return {"clips": self.clips, "frames": self.frames, "seconds": round(self.seconds, 3),
                "rates": {f"{r:g}": n for r, n in self.rates.items()}, "refused": self.refused}


def survey_totals(entries: Iterable[CorpusEntry]) -> SurveyTotals:
    """The totals of :func:`survey`'s entries."""
    entries = list(entries)
    clips = [e for e in entries if e.refused is None]
    rates: dict[float, int] = {}
    for e in clips:
        rates[e.fps] = rates.get(e.fps, 0) + 1
    return SurveyTotals(len(clips), sum(e.frames for e in clips), sum(e.seconds for e in clips),
                        dict(sorted(rates.items())), len(entries) - len(clips))
