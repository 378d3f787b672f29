"""Experiments: a grid of sequences x priors x view sets x particle counts x annealing layers x likelihood
variants x seeds, read from a TOML file, validated as a whole before anything runs.

File layout (every key is checked, unknown ones refused)::

    description = "Table 6.1 analogue"       # free text, shown in the table
    data_root = "../../../shared"            # where the data paths below are (relative to this file, or absolute)
    seed = 2009                              # master seed: run k of seed index i uses SeedSequence(seed).spawn(..)[i]
    seeds = 5                                # runs per configuration
    fps = 60                                 # rate of rendered sequences and trained models (default 60)
    baseline = "zero-velocity"               # the row others are compared with (default: the first prior)
    paired = "baseline"                      # paired differences against the baseline, or "all" pairs

    [tracking]                               # track's settings (tracker/app/schema.py), same names and defaults;
    particles = 1000                         # particles, annealing_layers and views: a value or a list of values
    views = [[0, 1, 2, 3], [0]]              # view sets
    annealing_layers = 3                     # default: track's (3)
    frames = 150                             # track frames 0..frames-1 (default: whole sequences)
    survival_rate = 0.5                      # also known_frames, resampling, ess_threshold, layer_diffusion_decay

    [[sequence]]                             # a sequence folder ...
    name = "bodytrack"
    path = "bodytrack/sequenceB_1"
    [[sequence]]                             # ... such as an imported video without ground truth:
    name = "T-pose"                          # its first poses (as initialise writes them; a folder with
    path = "seq"                             # ground truth starts from that unless init is given), and
    init = "init.npz"                        # optionally another method's reconstruction (TRC) that the
    reference = "static_0-12.trc"            # tables measure each prior's distance to; its frame
    reference_offset = 0                     # of the run's frame 0 (default: meta.json's first_video_frame, else 0)
    [[sequence]]                             # ... or a mocap clip the runner renders (and caches)
    name = "subject 16 walk"
    mocap = "mocap/cmu/16/16_15.amc"
    start = 0                                # synth options: start, frames, cameras, seed, noise, ...
    frames = 150
    turn = 90                                # degrees about the vertical: the walk in another direction
    joint_map = "mixamo_map.toml"            # a BVH whose joint names are not recognised (docs/guide/motion_capture.md)
    [[sequence]]                             # ... or two clips cross-faded: a change of activity
    name = "subject 2 walk then run"         # (data_tools.motion.transition; switch_at at the experiment's fps)
    mocap = "mocap/cmu/02/02_01.amc"
    then = "mocap/cmu/02/02_03.amc"
    switch_at = 120
    fade = 12

    [[prior]]
    label = "zero-velocity"                  # row label (default: the name)
    name = "zero-velocity"                   # a registered prior
    train_mocap = ["..."]                    # random-walk scale clips, like train's mocap (default: shipped walks)
    options = { prior_scale = 1.0 }
    [[prior]]
    label = "CRBM-3 (grown from 1)"
    name = "crbm"
    models = ["crbm3.pt"]                    # model files, or models the runner trains (and caches):
    train = [{ mocap = ["a.amc", "b.amc"], options = { order = 1 } },   # files, folders, "walks/*.bvh"
             { mocap = ["a.amc", { path = "c.amc", start = 0, frames = 600 }], options = { order = 3 } }]
                                             # (a clip's table may also give joint_map = "map.toml")
    [[prior]]
    label = "CRBM-3"                         # the same training repeated with several training seeds: one row
    name = "crbm"                            # per model ("CRBM-3, training seed 0", ...), and the report's
    train_seeds = [0, 1, 2, 3, 4]            # "over training seeds" table: the mean over the models, the spread
    train = [{ mocap = ["a.amc"] }]          # between models beside the spread over tracking seeds

    [[prior]]
    label = "CRBM + zero-velocity"           # a mixture: one [[prior.components]] table per component, each with
    name = "mixture"                         # its prior, options and models = [...] or train = {...} (trained and
    [[prior.components]]                     # cached like the others); written into the mixture's components
    prior = "crbm"                           # option ("crbm:gibbs_steps=10,zero-velocity"), the models handed over
    train = { mocap = ["a.amc"], options = { order = 1 } }   # in the components' order
    options = { gibbs_steps = 10 }
    [[prior.components]]
    prior = "zero-velocity"

    [[likelihood]]                           # variants (default: one edge-silhouette)
    label = "one-directional"
    name = "edge-silhouette"
    options = { bidirectional = false }

Paths: the data paths (a sequence's ``path``, ``init``, ``reference``, ``mocap``, ``skeleton``, ``then``,
``then_skeleton``, ``joint_map`` and ``then_joint_map``, and the training clips and skeletons of ``train`` and
``train_mocap``) are relative to the data root when the file declares ``data_root``, and relative to the file
otherwise; ``models`` are always relative to the file; absolute paths stay as they are. ``compare --data-root
DIR`` (the ``data_root`` argument of :func:`load_experiment` and
``tracker.compare``), or else the environment variable ``POSE_TRACKER_DATA_ROOT``, replaces the declared data root,
so that a file copied elsewhere, or data kept elsewhere, needs no edit; a file that declares no data root is not
affected by the environment variable, and refuses ``--data-root``.

Each run is identified by a hash of everything that determines its numbers (its settings, the sequence's
and the model files' content hashes, the package version), so a finished run is never redone and changing
one setting reruns only the runs it affects. No path enters the hash, so moving the data root (or the file)
leaves every finished run valid.

This module reads the file into the experiment's spec (:mod:`tracker.app.experiment_spec`);
:mod:`tracker.app.run_grid` expands that into runs, and :mod:`tracker.app.compare` prepares and runs them.
"""
from __future__ import annotations

import os
import shlex
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from data_tools.synthesis.synth_settings import SYNTH_OPTIONS, SynthConfig, renamed_views
from tracker.app.experiment_spec import (ClipSpec, Experiment, LikelihoodSpec, PriorSpec,  # noqa: F401 (re-exported)
                                         SequenceSpec, TrainSpec)
from tracker.app.run_grid import RunSpec, expand_runs, row_label, run_seed  # noqa: F401 (re-exported)
from tracker.core.errors import InputError
from tracker.engine.registry import GivenComponent, Option, PriorEntry

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TOP_KEYS = {"description", "data_root", "seed", "seeds", "fps", "baseline", "paired", "tracking", "sequence",
            "prior", "likelihood"}
#: The experiment's own settings at the top of the file (besides ``data_root`` and ``baseline``, which name a
#: folder and a row).
EXPERIMENT_OPTIONS = (
    Option("description", str, "", "free text, the tables' title"),
    Option("seed", int, 0, "master seed: seed index i of every configuration uses SeedSequence(seed).spawn(..)[i]",
           minimum=0),
    Option("seeds", int, 1, "tracking seeds (runs) per configuration", minimum=1),
    Option("fps", float, 60.0, "frame rate of rendered sequences and trained models", minimum=1.0, maximum=1000.0,
           unit="Hz"),
    Option("paired", str, "baseline", "paired differences against the baseline, or between all pairs of rows",
           choices=("baseline", "all")),
)
#: The environment variable that replaces an experiment file's ``data_root`` (``compare --data-root`` wins over it).
DATA_ROOT_ENV = "POSE_TRACKER_DATA_ROOT"
#: A sequence folder's keys (``path = ...``) besides its name: where its first poses come from, and a reference
#: reconstruction to measure the runs against.
FOLDER_KEYS = {"path", "init", "reference", "reference_offset"}
#: A rendered sequence's keys that describe a change of activity (data_tools.motion.transition) or how its clips are
#: read (joint maps), not the rendering.
TRANSITION_KEYS = {"then", "then_skeleton", "switch_at", "fade", "joint_map", "then_joint_map"}
#: A rendered sequence's rendering settings: those of ``pose-tracker synth`` (the frame rate is the experiment's),
#: and ``views``, the former name of ``cameras``.
RENDERING_KEYS = {o.name for o in SYNTH_OPTIONS if o.name != "fps"} | {"views"}
SEQUENCE_KEYS = {"name", "mocap", "skeleton"} | FOLDER_KEYS | TRANSITION_KEYS | RENDERING_KEYS
PRIOR_KEYS = {"label", "name", "options", "models", "train", "train_mocap", "train_seeds", "components"}
TRAIN_KEYS = {"mocap", "skeletons", "options", "seed"}
#: The keys of a ``[[prior.components]]`` table: one motion model of a prior with components (a mixture).
COMPONENT_KEYS = {"prior", "options", "model", "models", "train"}
LIKELIHOOD_KEYS = {"label", "name", "options"}


class _Where:
    """Builds one-line errors that name the experiment file and the entry."""

    def __init__(self, path: Path, data_root: Path | None = None):
        self.path = path
        self.data_root = data_root
        #: The command that downloads the CMU trials the file names to where its data paths are looked for.
        self.fetch_command = fetch_command(path)

    def error(self, entry: str, message: str) -> InputError:
        return InputError(f"{entry}: {message}" if entry else message, self.path)

    def keys(self, table: Any, allowed: set[str], entry: str) -> dict:
        if not isinstance(table, dict):
            raise self.error(entry, f"expected a table, got {type(table).__name__}")
        unknown = sorted(set(table) - allowed)
        if unknown:
            raise self.error(entry, f"unknown key(s) {', '.join(map(repr, unknown))} (allowed: "
                                    f"{', '.join(sorted(allowed))})")
        return table

    def file(self, value: Any, entry: str, folder: bool = False, data: bool = True) -> Path:
        """An existing file (or folder): a data path relative to the data root when there is one, otherwise (and
        for ``data=False``, the model files) relative to the experiment file."""
        if not isinstance(value, str) or not value:
            raise self.error(entry, f"expected a path, got {value!r}")
        p = Path(value).expanduser()
        base = self.data_root if data and self.data_root is not None else self.path.parent
        p = p if p.is_absolute() else (base / p)
        if not (p.is_dir() if folder else p.is_file()):
            cmu = data and self.data_root is not None and "mocap/cmu/" in value.replace("\\", "/")
            hint = f"; `{self.fetch_command}` downloads the CMU trials it names" if cmu else ""
            raise self.error(entry, f"{'folder' if folder else 'file'} not found: {p}{hint}")
        return p.resolve()

    def int_(self, value: Any, entry: str, minimum: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise self.error(entry, f"expected an integer >= {minimum}, got {value!r}")
        return value


def _clips(w: "_Where", value: Any, entry: str) -> list[ClipSpec]:
    """The training clips of one entry: a path, folder or glob pattern (:func:`~data_tools.motion.load.expand_mocap`:
    every mocap file a folder holds, recursively, or the pattern matches, in sorted order), or
    ``{ path = "...", start = 0, frames = 600, joint_map = "map.toml" }`` (its settings apply to every file)."""
    from data_tools.motion.load import expand_mocap, is_pattern
    from data_tools.motion.skeleton_points import read_joint_map

    settings: dict = {}
    if isinstance(value, dict):
        w.keys(value, {"path", "start", "frames", "joint_map"}, entry)
        frames = value.get("frames")
        settings = {"start": w.int_(value.get("start", 0), entry + " start", 0),
                    "frames": None if frames is None else w.int_(frames, entry + " frames", 3),
                    "joint_map": None if "joint_map" not in value else read_joint_map(w.file(value["joint_map"],
                                                                                             entry))}
        value = value.get("path")
    if not isinstance(value, str) or not value:
        raise w.error(entry, f"expected a path, got {value!r}")
    base = w.data_root if w.data_root is not None else w.path.parent
    path = Path(value).expanduser()
    if not is_pattern(value) and not (path if path.is_absolute() else base / path).exists():
        w.file(value, entry)  # the refusal of a missing file, with what fetches it
    try:
        files = expand_mocap(value, base)
    except InputError as exc:
        raise w.error(entry, f"{exc.reason}: {exc.path or value}") from None
    return [ClipSpec(f.resolve(), **settings) for f in files]


def _replicates(w: "_Where", spec: PriorSpec, entry_doc: dict, entry: str) -> list[PriorSpec]:
    """The rows of a ``train_seeds`` entry: the entry once per training seed, every one of its trainings run
    with that seed, labelled ``"LABEL, training seed S"``."""
    seeds = entry_doc["train_seeds"]
    if not isinstance(seeds, list):
        raise w.error(entry, f"train_seeds must be a list of training seeds, e.g. [0, 1, 2], got {seeds!r}")
    if not spec.train:
        raise w.error(entry, "train_seeds repeats the entry's trainings: it needs train = [...]")
    given = _as_list(entry_doc.get("train", [])) + [t for c in _as_list(entry_doc.get("components", []))
                                                    if isinstance(c, dict) for t in _as_list(c.get("train", []))]
    if any(isinstance(t, dict) and "seed" in t for t in given):
        raise w.error(entry, "give the training seeds either as train_seeds or as each training's seed, not both")
    seeds = [w.int_(s, f"{entry} train_seeds", 0) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise w.error(entry, f"train_seeds must be distinct integers >= 0, got {entry_doc['train_seeds']!r}")
    return [replace(spec, label=f"{spec.label}, training seed {s}", replicate_of=spec.label, training_seed=s,
                    train=tuple(replace(t, seed=s) for t in spec.train),
                    sources=tuple(replace(t, seed=s) if isinstance(t, TrainSpec) else t for t in spec.sources))
            for s in seeds]


def _trainings(w: "_Where", prior: str, value: Any, entry: str) -> list[TrainSpec]:
    """The ``train`` entries (a table or a list of tables) of the learned prior ``prior``."""
    from tracker.app.plugins import prior_entry
    from tracker.engine.registry import resolve_options

    spec, out = prior_entry(prior), []
    for j, t in enumerate(_as_list(value)):
        te = f"{entry} train {j + 1}"
        w.keys(t, TRAIN_KEYS, te)
        if spec.train is None:
            mixed = spec.composition is not None
            raise w.error(te, f"prior {prior} is not learned: it has nothing to train" + (
                " (its learned components are trained in [[prior.components]] tables, each with its own train = "
                "{ ... })" if mixed else ""))
        try:
            resolve_options(f"training {prior}", spec.train_options, t.get("options", {}))
        except InputError as exc:
            raise w.error(te, exc.reason) from None
        mocap = tuple(c for m in _as_list(t.get("mocap", [])) for c in _clips(w, m, te))
        if not mocap:
            raise w.error(te, "needs mocap = [training clips]")
        skels = tuple(w.file(m, te) for m in _as_list(t["skeletons"])) if "skeletons" in t else None
        options = _read_labels(w, dict(t.get("options", {})), mocap, te)
        out.append(TrainSpec(mocap, skels, options, w.int_(t.get("seed", 0), te, 0), prior))
    return out


def _read_labels(w: "_Where", options: dict, mocap: tuple[ClipSpec, ...], entry: str) -> dict:
    """``options`` with a ``labels`` pattern or sidecar file (:mod:`data_tools.motion.corpus`; a sidecar is a data path)
    read into one label per clip, in clip order: the labels themselves then identify the trained model, so that
    an edited sidecar trains anew, and a clip without its label is refused as the file is read."""
    from data_tools.motion.corpus import is_label_source, label_source

    if not is_label_source(options.get("labels")):
        return options
    base = w.data_root if w.data_root is not None else w.path.parent
    try:
        labels = label_source(options["labels"], base).training_labels([m.path for m in mocap],
                                                                       options.get("unlabelled"))
    except InputError as exc:
        raise w.error(entry, str(exc)) from None
    return {**options, "labels": ",".join(labels)}


def _components(w: "_Where", doc: dict, spec: PriorEntry, options: dict, entry: str
                ) -> tuple[dict, tuple[Path | TrainSpec, ...]]:
    """A prior's ``[[prior.components]]`` tables (``prior``, ``options``, ``model`` or ``models`` or ``train``),
    for a prior made of other priors (its registry entry's :attr:`~tracker.engine.registry.PriorEntry.composition`
    writes them into its option): the prior's options with that option written from them (without paths: a
    component's model files are the prior's, in order, so that no path enters a run's hash), and the model files
    and trainings in that order."""
    from tracker.app.plugins import prior_entry
    from tracker.engine.registry import resolve_options

    composition = spec.composition
    if composition is None:
        raise w.error(entry, f"prior {doc['name']} has no components (a mixture has)")
    if composition.option in options:
        raise w.error(entry, f"give the components either as options.{composition.option} or as "
                             "[[prior.components]] tables, not both")
    for key in ("models", "train"):
        if key in doc:
            raise w.error(entry, f"with [[prior.components]] each component gives its own {key}, not the prior")
    tables = doc["components"]
    if not isinstance(tables, list) or not all(isinstance(c, dict) for c in tables):
        raise w.error(entry, f"components are given as [[prior.components]] tables (each with prior = NAME) or as "
                             f"text, options = {{ {composition.option} = \"crbm,zero-velocity\" }}; got {tables!r}")
    if len(tables) < 2:
        raise w.error(entry, "[[prior.components]] must give two or more components")
    given, sources = [], []
    for k, c in enumerate(tables):
        ce = f"{entry} component {k + 1}"
        w.keys(c, COMPONENT_KEYS, ce)
        if "prior" not in c:
            raise w.error(ce, "needs prior = NAME (a registered prior)")
        try:
            component = prior_entry(c["prior"])
            values = c.get("options", {})
            if not isinstance(values, dict):
                raise InputError(f"options must be a table, got {values!r}")
            resolve_options(f"prior {c['prior']}", component.options, values)
        except InputError as exc:
            raise w.error(ce, exc.reason) from None
        ce = f"{entry} component {k + 1} ({c['prior']})"
        if "model" in c and "models" in c:
            raise w.error(ce, "give model = FILE or models = [FILE, ...], not both")
        named = [c["model"]] if "model" in c else _as_list(c.get("models", []))
        files = [w.file(m, ce, data=False) for m in named]
        trains = _trainings(w, c["prior"], c.get("train", []), ce)
        try:
            component.check_model_files(len(files) + len(trains), needs="models = [...] or train = ...")
        except InputError as exc:
            raise w.error(ce, exc.reason) from None
        sources += files + trains
        given.append(GivenComponent(c["prior"], values, len(files) + len(trains)))
    try:
        options = {**options, composition.option: composition.written(given)}
        resolve_options(f"prior {doc['name']}", spec.options, options)
    except InputError as exc:
        raise w.error(entry, exc.reason) from None
    return options, tuple(sources)


def _as_list(value: Any) -> list:
    return list(value) if isinstance(value, list) else [value]


def resolve_data_root(path: Path, declared: Any, given: str | Path | None = None) -> Path | None:
    """The data root of the experiment file ``path``: ``given`` (``compare --data-root``), else the environment
    variable :data:`DATA_ROOT_ENV`, else the file's ``data_root`` (``declared``, relative to the file); None when
    the file declares none. A root that is not a folder is one :class:`InputError` naming the file and the path."""
    if declared is None:
        if given is not None:
            raise InputError(f"--data-root {given} given, but the file declares no data_root (its data paths are "
                             f"relative to the file)", path)
        return None
    if not isinstance(declared, str) or not declared:
        raise InputError(f"data_root: expected a folder, got {declared!r}", path)
    env = os.environ.get(DATA_ROOT_ENV) or None
    if given is not None:
        root, source = Path(given).expanduser(), "--data-root"
    elif env is not None:
        root, source = Path(env).expanduser(), DATA_ROOT_ENV
    else:
        root, source = Path(declared).expanduser(), "data_root"
        root = root if root.is_absolute() else path.parent / root
    if not root.is_dir():
        raise InputError(f"data root not found: {root} ({source}); `{fetch_command(path, given)}` downloads the "
                         f"CMU trials the file names into it", path)
    return root.resolve()


def fetch_command(path: Path, given: str | Path | None = None) -> str:
    """The ``pose-tracker fetch`` command that puts the CMU trials the experiment file ``path`` names where its
    data paths are looked for: with ``--data-root`` when the data root is ``given`` or comes from the environment
    variable :data:`DATA_ROOT_ENV` (the same command in another shell, or a file with another data_root, would
    place them elsewhere)."""
    root = given if given is not None else (os.environ.get(DATA_ROOT_ENV) or None)
    where = f" --data-root {shlex.quote(str(Path(root).expanduser()))}" if root is not None else ""
    return f"pose-tracker fetch --for {shlex.quote(str(path))}{where}"


def _tracking(w: "_Where", table: Any) -> dict[str, Any]:
    """The ``[tracking]`` table: every setting of :data:`tracker.app.schema.EXPERIMENT_SETTINGS`, given (checked
    by its option: one line naming the file, the key and the rule) or its default; the settings of
    :data:`~tracker.app.schema.GRID_AXES` as lists of values (``views``: of view sets, None for all views)."""
    from tracker.app.schema import EXPERIMENT_SETTINGS, GRID_AXES, setting

    table = w.keys(table, set(EXPERIMENT_SETTINGS), "[tracking]")
    grid: dict[str, Any] = {}
    for name in EXPERIMENT_SETTINGS:
        option, entry = setting(name), f"[tracking] {name}"
        value = table.get(name)
        if name == "views":
            if value is not None and not isinstance(value, list):
                raise w.error(entry, f"expected a list of camera indices or a list of such lists, got {value!r}")
            sets = [None] if value is None else (value if value and isinstance(value[0], list) else [value])
            for vs in sets:
                if vs is not None and (not isinstance(vs, list) or not vs or len(set(map(repr, vs))) != len(vs)):
                    raise w.error(entry, f"each view set must list distinct camera indices, got {vs!r}")
            grid[name] = [None if vs is None else list(_checked(w, option, vs, "[tracking]")) for vs in sets]
        elif name in GRID_AXES:
            values = _as_list(option.default if value is None else value)
            if not values:
                raise w.error(entry, "expected a value or a non-empty list, got []")
            grid[name] = [_checked(w, option, v, "[tracking]") for v in values]
        else:
            grid[name] = option.default if value is None else _checked(w, option, value, "[tracking]")
    if grid["frames"] is not None and grid["known_frames"] >= grid["frames"]:
        raise w.error("[tracking] frames", f"must exceed known_frames ({grid['known_frames']}), got "
                                           f"{grid['frames']}")
    return grid


def _checked(w: "_Where", option: Option, value: Any, table: str = "") -> Any:
    """``value`` checked by ``option``; its refusal is one line naming the file, the ``table`` (``[tracking]``;
    empty at the top level) and the key: ``exp.toml: [tracking] particles must be at least 1 ..., got 0``."""
    try:
        return option.parse(value, "")
    except InputError as exc:
        raise InputError(f"{table} {exc.reason[2:]}".strip(), w.path) from None


def load_experiment(path: str | Path, data_root: str | Path | None = None) -> Experiment:
    """Read and validate an experiment file; every problem is one :class:`InputError` naming the entry.

    ``data_root`` replaces the file's ``data_root`` (as does the environment variable ``POSE_TRACKER_DATA_ROOT``
    when ``data_root`` is None); see the module docstring."""
    from tracker.app.plugins import likelihood_entry, prior_entry
    from tracker.engine.registry import resolve_options

    path = Path(path).resolve()
    w = _Where(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except FileNotFoundError:
        raise InputError("experiment file not found", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read experiment file ({exc})", path) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", path) from None
    w.keys(doc, TOP_KEYS, "")
    w.data_root = resolve_data_root(path, doc.get("data_root"), data_root)
    w.fetch_command = fetch_command(path, data_root)
    top = {o.name: o.default if doc.get(o.name) is None else _checked(w, o, doc[o.name]) for o in EXPERIMENT_OPTIONS}
    seed, seeds, fps = top["seed"], top["seeds"], top["fps"]
    grid = _tracking(w, doc.get("tracking", {}))
    from data_tools.motion.skeleton_points import read_joint_map
    sequences = []
    for i, s in enumerate(doc.get("sequence", [])):
        entry = f"[[sequence]] {i + 1}"
        w.keys(s, SEQUENCE_KEYS, entry)
        name = s.get("name") or f"sequence {i + 1}"
        entry = f"sequence {name!r}"
        if ("path" in s) == ("mocap" in s):
            raise w.error(entry, "give either path (a sequence folder) or mocap (a clip to render)")
        if "path" in s:
            extra = sorted(set(s) - {"name"} - FOLDER_KEYS)
            if extra:
                raise w.error(entry, f"{', '.join(extra)} apply to rendered sequences (mocap = ...), not to path")
            if "reference_offset" in s and "reference" not in s:
                raise w.error(entry, "reference_offset applies to a reference: give reference = \"FILE.trc\"")
            offset = None if "reference_offset" not in s else w.int_(s["reference_offset"],
                                                                       f"{entry} reference_offset", 0)
            sequences.append(SequenceSpec(name, path=w.file(s["path"], entry, folder=True),
                                          init=w.file(s["init"], f"{entry} init") if "init" in s else None,
                                          reference=(w.file(s["reference"], f"{entry} reference")
                                                     if "reference" in s else None),
                                          reference_offset=offset))
        else:
            folder_only = sorted(set(s) & (FOLDER_KEYS - {"path"}))
            if folder_only:
                raise w.error(entry, f"{', '.join(folder_only)} apply to sequence folders (path = ...), not to "
                                     "rendered sequences, which start from their ground truth")
            synth = {k: v for k, v in s.items() if k not in ("name", "mocap", "skeleton")}
            try:
                synth = renamed_views(synth, f"{path}: {entry}")
            except InputError as exc:
                raise w.error(entry, exc.reason) from None
            try:  # every rendering setting checked now, not when the runner reaches this sequence
                rendering = SynthConfig.of({"fps": float(fps), **{k: v for k, v in synth.items()
                                                                  if k not in TRANSITION_KEYS}})
                rendering.check_missing_camera(rendering.views, "missing_camera")
            except InputError as exc:
                raise w.error(entry, exc.reason) from None
            for key in ("switch_at", "fade"):
                if key in synth:
                    w.int_(synth[key], f"{entry} {key}", 0 if key == "fade" else 1)
            for key in ("then", "then_skeleton"):  # a transition's second clip, relative to the file like mocap
                if key in s:
                    synth[key] = str(w.file(s[key], entry))
            for key in ("joint_map", "then_joint_map"):  # kept as read, so the cached rendering's hash covers it
                if key in s:
                    synth[key] = read_joint_map(w.file(s[key], entry))
            if "then_joint_map" in s and "then" not in s:
                raise w.error(entry, "then_joint_map applies to a transition: give the second clip (then = ...)")
            sequences.append(SequenceSpec(name, mocap=w.file(s["mocap"], entry),
                                          skeleton=w.file(s["skeleton"], entry) if "skeleton" in s else None,
                                          synth=synth))
    if not sequences:
        raise w.error("", "no [[sequence]] entries")
    if len({s.name for s in sequences}) != len(sequences):
        raise w.error("[[sequence]]", "sequence names must be unique")

    priors = []
    for i, p in enumerate(doc.get("prior", [])):
        w.keys(p, PRIOR_KEYS, f"[[prior]] {i + 1}")
        if "name" not in p:
            raise w.error(f"[[prior]] {i + 1}", "needs a name (a registered prior)")
        label = p.get("label", p["name"])
        entry = f"prior {label!r}"
        try:
            spec = prior_entry(p["name"])
            resolve_options(f"prior {p['name']}", spec.options, p.get("options", {}))
        except InputError as exc:
            raise w.error(entry, exc.reason) from None
        models = tuple(w.file(m, entry, data=False) for m in _as_list(p.get("models", [])))
        trains = _trainings(w, p["name"], p.get("train", []), entry)
        options, sources = dict(p.get("options", {})), ()
        if "components" in p:
            options, sources = _components(w, p, spec, options, entry)
            models = tuple(s for s in sources if isinstance(s, Path))
            trains = [s for s in sources if isinstance(s, TrainSpec)]
        else:  # model files that the options name: relative to the file, as its models are, checked as it is read
            options = spec.located(options, lambda m: str(w.file(m, f"{entry} components", data=False).resolve()),
                                   f"prior {entry}")
        try:
            spec.check_model_files(len(models) + len(trains), needs="models = [...] or train = [...]")
        except InputError as exc:
            raise w.error(entry, exc.reason) from None
        train_mocap = (tuple(c for m in _as_list(p["train_mocap"]) for c in _clips(w, m, entry))
                       if "train_mocap" in p else None)
        prior = PriorSpec(label, p["name"], options, models, tuple(trains), train_mocap, sources=sources)
        priors += _replicates(w, prior, p, entry) if "train_seeds" in p else [prior]
    if not priors:
        raise w.error("", "no [[prior]] entries")
    if len({p.label for p in priors}) != len(priors):
        raise w.error("[[prior]]", "prior labels must be unique (set label = ...)")

    likelihoods = []
    for i, lk in enumerate(doc.get("likelihood", [{"name": "edge-silhouette"}])):
        w.keys(lk, LIKELIHOOD_KEYS, f"[[likelihood]] {i + 1}")
        name = lk.get("name", "edge-silhouette")
        label = lk.get("label", name)
        try:
            resolve_options(f"likelihood {name}", likelihood_entry(name).options, lk.get("options", {}))
        except InputError as exc:
            raise w.error(f"likelihood {label!r}", exc.reason) from None
        likelihoods.append(LikelihoodSpec(label, name, dict(lk.get("options", {}))))
    if len({lk.label for lk in likelihoods}) != len(likelihoods):
        raise w.error("[[likelihood]]", "likelihood labels must be unique")
    baseline = doc.get("baseline", priors[0].label)
    if baseline not in {p.label for p in priors}:
        group = [p.label for p in priors if p.replicate_of == baseline]
        raise w.error("baseline", f"{baseline!r} repeats its training (train_seeds): name one of its rows, e.g. "
                                  f"{group[0]!r}" if group else f"{baseline!r} is not a prior label")
    return Experiment(path, top["description"], seed, seeds, fps, baseline, top["paired"], grid, sequences, priors,
                      likelihoods, w.data_root)
