"""The public Python API (re-exported by ``import tracker``): load, synthesize, build, train, track.

Everything the command line does goes through these functions, so a notebook
and the shell produce the same numbers and the same files::

    import tracker
    seq = tracker.synthesize("07_02.amc", out="walk_seq", frames=60)
    model = tracker.train("crbm", ["07_01.amc"], order=1, epochs=300, seed=0)
    model.save("crbm1.pt")
    for prior, models in [("zero-velocity", []), ("crbm", ["crbm1.pt"])]:
        result = tracker.track(seq, prior, models=models, particles=500, seed=0)
        print(prior, result.mean_error)

Random numbers: every function that draws takes ``seed`` (an int, a
``numpy.random.SeedSequence`` or a ``numpy.random.Generator``); nothing touches
global random state.
"""
from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Mapping, Sequence as Seq

import numpy as np

from data_tools.motion.corpus import is_label_source, label_source
from data_tools.motion.load import load_retargeted, load_training_clips
from data_tools.motion.retarget import RetargetResult
from data_tools.sequences.sequence import Sequence, read_sequence
from tracker.app import schema
from tracker.app.schema import (FILTER_OPTIONS, KEYPOINT_LIKELIHOOD, RECORDED_SETTINGS, SILHOUETTE_LIKELIHOOD,
                                TRACK_SETTINGS)
from tracker.app.schema import TRACK_ANNEALING_LAYERS  # noqa: F401  (the API names the default: tracker.track)
from tracker.app.plugins import (  # the discovery functions of the API
    available_likelihoods, available_priors, likelihood_entry, prior_entry,  # noqa: F401  (re-exported)
)
from tracker.app.threads import configured_threads, sync_torch_threads
from tracker.app.walk_scale import walk_scale
from tracker.app.clips import load_clips  # noqa: F401  (tracker.load_clips)
from tracker.app.tracking import (
    TrackingInterrupted, TrackingResult, check_frames, check_views, records_call, run_tracking, seed_description,
)
from tracker.core.arrays import device_name
from tracker.core.errors import InputError
from tracker.core.representation import step_rms
from tracker.engine.filter import FilterConfig
from tracker.engine.likelihood import Likelihood
from tracker.engine.prior import MotionPrior
from tracker.engine.recording import DEFAULT_RECORD, FrameStep
from tracker.engine.registry import PRIORS, LikelihoodContext, PriorContext, TrainingData, resolve_options

if TYPE_CHECKING:  # the renderer (trimesh) is imported by synthesize, not by every command
    from data_tools.synthesis.synth import SynthConfig

SeedLike = int | np.random.SeedSequence | np.random.Generator

log = logging.getLogger(__name__)


def make_rng(seed: SeedLike) -> np.random.Generator:
    """A numpy Generator from an int, a SeedSequence or a Generator (returned as it is)."""
    if isinstance(seed, np.random.Generator):
        return seed
    if isinstance(seed, (int, np.integer)):
        seed = schema.setting("seed").parse(int(seed), "the run")  # the schema's bounds of a seed
    return np.random.default_rng(seed)


# -- data ---------------------------------------------------------------------------------------------------

def load_sequence(path: str | Path) -> Sequence:
    """A sequence folder in pose-tracker's layout or PARSEC bodytrack's (docs/reference/file_formats.md)."""
    return read_sequence(path)


def load_clip(mocap: str | Path, skeleton: str | Path | None = None, fps: float | None = 60.0,
              length_unit: float | None = None, joint_map: str | Path | Mapping | None = None) -> RetargetResult:
    """A mocap file (AMC with its ASF, or BVH) retargeted to the 15-cone body model at ``fps`` Hz (None: the
    file's own rate; other rates are interpolated). ``joint_map`` (a JSON or TOML file, or a mapping of body
    points to the file's joint names) is for skeletons whose names are not recognised
    (docs/guide/motion_capture.md). Converted clips are cached (:func:`load_clips`)."""
    return load_retargeted(mocap, skeleton, fps, length_unit, joint_map)


#: A mean retarget residual (mm) above which a conversion is suspect: a well-read file fits within a few mm.
RESIDUAL_WARNING_MM = 10.0


def read_clip(mocap: str | Path, skeleton: str | Path | None = None, fps: float | None = 60.0,
              length_unit: float | None = None, joint_map: str | Path | Mapping | None = None):
    """``(clip, retargeted)``: a mocap file read (its reader's notes logged) and retargeted at ``fps`` Hz, afresh
    (:func:`load_clip` takes it from the cache of converted clips); a mean retarget residual above
    :data:`RESIDUAL_WARNING_MM` is warned of, naming the likely cause."""
    from data_tools.motion.load import load_mocap
    from data_tools.motion.retarget import retarget

    clip = load_mocap(mocap, skeleton, length_unit, joint_map=joint_map)
    name = Path(mocap).name
    for note in clip.notes:
        log.info(f"note: {name}: {note}")
    result = retarget(clip, fps=fps)
    if result.mean_residual > RESIDUAL_WARNING_MM:
        log.warning(f"{name}: mean retarget residual {result.mean_residual:.1f} mm; a well-read file fits within a "
                    "few mm, and tens of mm point to a wrong length unit (--length-unit) or joint mapping "
                    "(--joint-map): see docs/guide/motion_capture.md")
    return clip, result


def synthesize(mocap: str | Path | RetargetResult, out: str | Path, *, skeleton: str | Path | None = None,
               config: SynthConfig | None = None, progress: Callable | None = None, overwrite: bool = False,
               length_unit: float | None = None, then: str | Path | RetargetResult | None = None,
               then_skeleton: str | Path | None = None, switch_at: int | None = None, fade: int = 12,
               joint_map: str | Path | Mapping | None = None, then_joint_map: str | Path | Mapping | None = None,
               overwrite_flag: str = "overwrite=True", **settings) -> Sequence:
    """Render a mocap clip (a file, or a clip from :func:`load_clip`) into a synthetic multi-view sequence
    folder ``out`` and return it. ``settings`` are the rendering settings of
    :data:`~data_tools.synthesis.synth_settings.SYNTH_OPTIONS` (``cameras``, ``frames``, ``seed``, ``noise``, ...;
    or all of them as a ``config``). A non-empty ``out`` is refused unless ``overwrite`` (``overwrite_flag``: how the
    refusal says so). (``views=N``, the former name of ``cameras``, still works and logs a deprecation warning:
    :func:`track`'s ``views`` are camera indices.)

    With ``then`` (a second clip) the person changes activity: the clip until frame ``switch_at`` (at the
    output rate, before ``start``/``frames`` cut the result), cross-faded over ``fade`` frames into ``then``
    (:func:`data_tools.motion.transition.cross_fade`; e.g. a walk into a run of the same subject). ``joint_map`` and
    ``then_joint_map`` name the files' joints as :func:`load_clip`'s does."""
    from data_tools.io.files import check_output_folder
    from data_tools.motion.transition import cross_fade
    from data_tools.synthesis.synth import SynthConfig, synthesize as render_sequence
    from data_tools.synthesis.synth_settings import renamed_views

    # before any work; the refusal says how the caller asks to replace the folder
    check_output_folder(out, empty=not overwrite, replaceable=("cameras.json", "meta.json"),
                        overwrite_flag=overwrite_flag)
    settings = {k: v for k, v in renamed_views(settings, "synthesize").items() if v is not None}  # None: default
    if config is not None and settings:
        raise InputError(f"give the rendering settings in config or as keywords, not both ({', '.join(settings)})")
    config = config or SynthConfig.of(settings)
    if then is None and (switch_at is not None or then_joint_map is not None):
        raise InputError(f"{'switch_at' if switch_at is not None else 'then_joint_map'} applies to a transition: "
                         "give the second clip (then = ...)")
    if then is not None and switch_at is None:
        raise InputError("a transition (then = ...) needs switch_at, the frame where the second clip has taken over")
    clip = mocap if isinstance(mocap, RetargetResult) else read_clip(mocap, skeleton, config.fps, length_unit,
                                                                      joint_map)[1]
    source = str(mocap) if not isinstance(mocap, RetargetResult) else clip.source
    name = Path(source).name
    if then is not None:
        second = then if isinstance(then, RetargetResult) else read_clip(then, then_skeleton, config.fps,
                                                                          length_unit, then_joint_map)[1]
        clip, change = cross_fade(clip, second, switch_at, fade)
        log.info(f"transition: {name} until frame {change.fade_start}, cross-faded into "
                 f"{Path(getattr(then, 'source', then)).name} (from its frame {change.second_start}) by frame "
                 f"{change.switch}")
        source = clip.source
    written = render_sequence(clip, out, config, source=source, progress=progress, overwrite=overwrite)
    log.info(f"{name}: "
             f"{written.n_frames} frames x {config.views} cameras at {clip.fps:g} fps -> {written.root} "
             f"({written.render_seconds / written.n_frames * 1000:.0f} ms per frame to render and write)")
    return read_sequence(out)


def random_walk_scale(seq: Sequence, train_mocap: Iterable[str | Path] | None = None) -> np.ndarray:
    """Per-dof random-walk scale ``(D,)`` for ``seq``: the RMS frame-to-frame change of training clips at the
    sequence's frame rate (default: the shipped subject-7 walks, whose scale is shipped for the usual rates,
    :mod:`tracker.app.walk_scale`), or a bodytrack folder's ``PoseParameters.txt``."""
    if seq.layout == "bodytrack":
        if seq.diffusion_std is None:
            raise InputError("bodytrack folder has no PoseParameters.txt for the random-walk scale", seq.root)
        return seq.diffusion_std
    if seq.fps is None:
        raise InputError("the sequence states no frame rate (groundtruth.npz or meta.json 'fps')", seq.root)
    if train_mocap is None:
        return walk_scale(seq.fps)
    return step_rms([r.poses for r in load_training_clips(list(train_mocap), None, seq.fps)])


def show(sequence: Sequence | str | Path, *, frame: int = 0, poses: str | Path | np.ndarray | None = None,
         out: str | Path | None = None, video: str | Path | None = None,
         progress: Callable | None = None) -> list[str]:
    """Draw the projected body model over every view of a sequence frame: the ground truth, or ``poses`` (an
    ``estimates.npz`` or a ``T x D`` array, drawn over the ground truth where there is one), or a bodytrack
    folder's initial pose. Writes the grid of views of ``frame`` to ``out`` (.png) and, with ``video`` (.mp4),
    every frame; returns one line per file written."""
    import cv2

    from data_tools.io.files import atomic_path
    from data_tools.sequences.estimates import read_poses_file
    from tracker.app.visualize import overlay_grid, write_video

    seq = sequence if isinstance(sequence, Sequence) else load_sequence(sequence)
    name, source = None, seq.root
    if isinstance(poses, (str, Path)):
        name, source, poses = Path(poses).stem, poses, read_poses_file(poses, "poses", seq.model)
    elif poses is not None:
        name, poses = "estimate", np.asarray(poses, float)
    drawn = poses
    if drawn is None:
        drawn = seq.groundtruth.poses if seq.groundtruth is not None else seq.initial_poses
    if drawn is None:
        raise InputError("the sequence has no ground truth or initial pose; give poses", seq.root)
    views = list(range(seq.n_views))
    seq.check_frame(frame)
    if frame >= len(drawn):
        raise InputError(f"no pose for frame {frame}: {len(drawn)} pose(s) available", source)
    truth = seq.groundtruth.poses if poses is not None and seq.groundtruth is not None else None

    def picture(k: int) -> np.ndarray:
        if poses is not None:  # the estimate over the ground truth, where the sequence has one
            gt = truth[k] if truth is not None and k < len(truth) else None
            return overlay_grid(seq, drawn[k], k, views, f"frame {k}", 2, truth=gt, estimate_name=name)
        return overlay_grid(seq, drawn[k], k, views, f"frame {k}")

    written = []
    if out is not None:
        out = Path(out)
        with atomic_path(out) as tmp:
            if not cv2.imwrite(str(tmp), cv2.cvtColor(picture(frame), cv2.COLOR_RGB2BGR)):
                raise InputError("cannot write image", out)
        written.append(f"frame {frame}, {seq.n_views} views -> {out}")
    if video is not None:
        n = min(seq.n_frames, len(drawn))
        frames = range(n) if progress is None else progress(range(n))
        write_video(Path(video), (picture(k) for k in frames), seq.fps or 25.0)
        written.append(f"{n} frames -> {video}")
    return written


# -- building -------------------------------------------------------------------------------------------------

def build_prior(name: str, sequence: Sequence | str | Path | None = None, models: Seq[str | Path | Any] = (), *,
                train_mocap: Iterable[str | Path] | None = None, step_std: np.ndarray | None = None,
                device: str = "cpu", **options) -> MotionPrior:
    """The registered prior ``name`` for ``sequence`` (a loaded sequence or its folder: the prior takes its body
    model and frame rate), from its models (learned priors: model files, or the models :func:`train` returns)
    and options: ``build_prior("mixture", seq, models=[model])``.

    Random-walk priors take their scale from ``step_std`` ``(D,)`` if given, else from ``train_mocap``
    clips (default: the shipped walks) or the bodytrack folder (:func:`random_walk_scale`). Learned priors
    with a torch path sample on ``device`` (``"cpu"``, ``"cuda"``, ``"cuda:N"``).
    """
    entry = prior_entry(name)
    if sequence is None:
        raise InputError(f"build_prior needs the sequence the prior will track (its body model and frame rate): "
                         f"tracker.build_prior({name!r}, sequence, models=[...])")
    if isinstance(sequence, (str, os.PathLike)):
        sequence = load_sequence(sequence)
    models = [Path(m) if isinstance(m, (str, os.PathLike)) else m for m in models]
    entry.check_model_files(len(models), needs=f"a model file (train one with: pose-tracker train --prior {name})")
    resolved = entry.resolve(options, models)
    source = (lambda: step_std) if step_std is not None else (lambda: random_walk_scale(sequence, train_mocap))
    context = PriorContext(sequence.model, sequence.fps, device_name(device), str(sequence.root), source)
    prior = entry.build(context, list(resolved.model_files), resolved.options)
    sync_torch_threads()  # a learned prior has imported torch by now
    return prior


def build_likelihood(name: str, sequence: Sequence, views: Iterable[int] | None = None, *, device: str = "cpu",
                     **options) -> Likelihood:
    """The registered likelihood ``name`` for the cameras ``views`` (default all) of ``sequence``, scoring on
    the torch ``device`` (``"cpu"``, the default, is the CPU path; ``"cuda"`` the GPU path), with the threads
    this process was given (:func:`tracker.set_threads`; default the available cores)."""
    entry = likelihood_entry(name)
    views = check_views(views, sequence.n_views, sequence.root)
    rig = sequence.rig.subset(views)
    if len({(c.width, c.height) for c in rig.cameras}) > 1:  # the likelihood scores every view at one size
        listed = ", ".join(f"{c.name} {c.width}x{c.height}" for c in rig.cameras)
        raise InputError(f"the views' image sizes differ ({listed}): tracking needs one size for every view (crop "
                         "or pad the images and their principal points to it, or choose views of one size)",
                         sequence.root)
    resolved = resolve_options(f"likelihood {name}", entry.options, options)
    device = device_name(device)
    context = LikelihoodContext(sequence.model, rig, device, configured_threads())
    likelihood = entry.build(context, resolved)
    sync_torch_threads()  # the GPU path has imported torch
    return likelihood


# -- training -------------------------------------------------------------------------------------------------

def train(prior: str, mocap: str | Path | Iterable[str | Path] | Iterable[RetargetResult], *,
          skeletons: Iterable[str | Path] | None = None, fps: float = 60.0, seed: SeedLike = 0,
          progress: Callable[[int, int, dict], None] | None = None, checkpoint: str | Path | None = None,
          resume: bool = False, joint_maps: Iterable[str | Path | Mapping | None] | str | Path | None = None,
          **options) -> Any:
    """Train the learned prior ``prior`` on mocap files (or retargeted clips) of any subjects and lengths.

    ``mocap`` is a file, folder or glob pattern, or a list of them, or of retargeted clips (:func:`load_clips`;
    converted clips are cached). Each AMC pairs with its own skeleton (``skeletons``: one for all or one per
    file; default ``<subject>.asf`` beside it); ``joint_maps`` likewise (one for all, one per file, None or
    ``"none"`` for a file whose joint names are recognised). Every clip is resampled to ``fps`` Hz.
    ``options`` are the prior's training options (see ``pose-tracker train --prior NAME --help``). Returns the
    trained model;
    ``model.save(path)`` writes its file (an existing one only with ``overwrite=True``).
    With ``checkpoint`` (a file path), a resumable prior's training state is saved there every
    ``checkpoint_every`` epochs (its option) and when the training is interrupted (``KeyboardInterrupt``);
    ``resume=True`` continues from it to the model an uninterrupted run gives.
    A prior's ``labels`` option (the FCRBM's) takes, besides one label per clip in clip order, a pattern over
    file names or a sidecar file with ``#KEY`` (``"dataset-2_{content}_{style}_{take}#style"``,
    :mod:`data_tools.motion.corpus`): each clip's label is read from its file.
    """
    entry = prior_entry(prior)
    if entry.train is None:
        trainable = [n for n in available_priors() if PRIORS.get(n).train is not None]
        raise InputError(f"prior {prior} is not learned; trainable priors: {', '.join(trainable)}")
    resolved = resolve_options(f"training {prior}", entry.train_options, options)
    labelled = label_source(resolved["labels"]) if is_label_source(resolved.get("labels")) else None
    if labelled is not None:
        labelled.training_keys()  # a pattern or file without its key is refused before any clip is converted
    items = [mocap] if isinstance(mocap, (str, Path)) else list(mocap)
    if not items:
        raise InputError("no training clips given")
    in_memory = [isinstance(c, RetargetResult) for c in items]
    if any(in_memory) and not all(in_memory):
        raise InputError("give training clips either all as files or all as retargeted clips, not mixed")
    if all(in_memory):  # retargeted clips carry their own frame rate
        rates = sorted({float(c.fps) for c in items})
        if len(rates) > 1:
            raise InputError(f"training clips have different frame rates ({', '.join(f'{r:g}' for r in rates)} "
                             "Hz); retarget them at one rate")
        clips, sources, fps = items, [c.source for c in items], rates[0]
    else:
        clips = load_training_clips(items, skeletons, fps, joint_maps)
        sources = [c.source for c in clips]
    if labelled is not None:
        resolved["labels"] = ",".join(labelled.training_labels(sources, resolved.get("unlabelled")))
    data = TrainingData(tuple(c.poses for c in clips), fps, clips[0].model, tuple(sources))
    extra = {}
    if resume:
        if not entry.resumable:
            raise InputError(f"training of prior {prior} cannot be resumed")
        extra["resume"] = True
    from tracker.app.checkpoint import training_checkpoint

    import torch  # noqa: F401  (every learned prior trains with torch: imported here, given the run's threads)

    sync_torch_threads()
    with training_checkpoint(checkpoint, sources, skeletons, resume, entry.resumable):  # saved when interrupted
        return entry.train(data, resolved, make_rng(seed), progress,
                           None if checkpoint is None else Path(checkpoint), **extra)


# -- tracking -------------------------------------------------------------------------------------------------

def split_options(prior: str | MotionPrior, likelihood: str | Likelihood, options: Mapping[str, Any]
                  ) -> tuple[dict, dict]:
    """``options`` split between the prior and the likelihood given by name, each option going to the one that
    declares it; an option neither declares (or one for a ready object) is an :class:`InputError` naming both
    lists."""
    declared = {}
    for kind, plugin, entry in (("prior", prior, prior_entry), ("likelihood", likelihood, likelihood_entry)):
        declared[kind] = {o.name for o in entry(plugin).options} if isinstance(plugin, str) else set()
    out: dict[str, dict] = {"prior": {}, "likelihood": {}}
    for name, value in options.items():
        kind = next((k for k in ("prior", "likelihood") if name in declared[k]), None)
        if kind is None:
            lists = "; ".join(f"{k} {p if isinstance(p, str) else 'object'}: {', '.join(sorted(declared[k])) or 'none'}"
                              for k, p in (("prior", prior), ("likelihood", likelihood)))
            raise InputError(f"track takes no option {name!r} (the options of {lists}; the run's settings: "
                             f"{', '.join(TRACK_SETTINGS)})")
        out[kind][name] = value
    return out["prior"], out["likelihood"]


def _refuse_options_of_the_other_default(chosen: str, options: Mapping[str, Any], seq: Sequence) -> None:
    """An option of the keypoint likelihood, given to a run whose default likelihood (:func:`default_likelihood`)
    is the one without keypoints, is refused naming why: the sequence has none."""
    keypoints = {o.name for o in likelihood_entry(KEYPOINT_LIKELIHOOD).options}
    theirs = sorted(n for n in options if n in keypoints - {o.name for o in likelihood_entry(chosen).options})
    if theirs:
        raise InputError(f"{theirs[0]} does not apply to the {chosen} likelihood, which this sequence takes (it has "
                         "no keypoints)", seq.root)


def model_name(model: str | Path | Any) -> str:
    """How ``result.json`` names a prior's model: its file, or the kind of a model given in memory."""
    return str(model) if isinstance(model, (str, os.PathLike)) else f"{type(model).__name__} (in memory)"


def split_settings(options: Mapping[str, Any]) -> tuple[dict, dict]:
    """``options`` split into the run's settings (:data:`tracker.app.schema.TRACK_SETTINGS`) and the rest (the
    plugins' options)."""
    run = {k: v for k, v in options.items() if k in TRACK_SETTINGS}
    return run, {k: v for k, v in options.items() if k not in TRACK_SETTINGS}


def run_settings(given: Mapping[str, Any], sequence: Sequence) -> dict[str, Any]:
    """Every setting of a run (:data:`tracker.app.schema.TRACK_SETTINGS`), from ``given`` (checked against its
    option) or its default; ``views`` as the camera indices tracked (default all), ``seed`` as given (an int,
    a ``SeedSequence`` or a ``Generator``: :func:`make_rng` checks it)."""
    seed = given.get("seed", schema.setting("seed").default)
    values = schema.check({k: v for k, v in given.items() if k != "seed" and v is not None}, "track")
    out = {**schema.defaults(), **values, "seed": seed}
    out["views"] = check_views(out["views"], sequence.n_views, sequence.root)
    out["device"] = device_name(out["device"])
    return out


def default_likelihood(sequence: Sequence) -> str:
    """The likelihood a run takes unless told: :data:`KEYPOINT_LIKELIHOOD` for a sequence with 2-D keypoints
    (``seq/keypoints/``), else :data:`SILHOUETTE_LIKELIHOOD`."""
    return KEYPOINT_LIKELIHOOD if getattr(sequence, "keypoints", None) is not None else SILHOUETTE_LIKELIHOOD


@records_call
def track(sequence: Sequence | str | Path, prior: str | MotionPrior = "zero-velocity", *,
          models: Seq[str | Path | Any] = (), likelihood: str | Likelihood | None = None,
          init: np.ndarray | None = None, train_mocap: Iterable[str | Path] | None = None,
          step_std: np.ndarray | None = None,
          record: Iterable[str] | Mapping[str, Callable[[FrameStep], Any]] = DEFAULT_RECORD,
          on_frame: Callable[[FrameStep, float | None], None] | None = None,
          checkpoint: str | Path | None = None, resume: bool = False, **settings) -> TrackingResult:
    """Track a person through ``sequence`` with a particle filter and return a :class:`TrackingResult`.

    ``settings`` are the run's settings and the prior's and likelihood's options. The run's settings are
    declared in :mod:`tracker.app.schema` (each with its type, default, bounds and unit; the list is at the end
    of this docstring): ``particles`` (default 1000), ``views`` (camera indices, default all), ``frames`` (track
    frames ``known_frames .. frames-1``, default to the end), ``seed`` (an int, a ``numpy.random.SeedSequence``
    or a ``numpy.random.Generator``), ``annealing_layers`` (default :data:`TRACK_ANNEALING_LAYERS`, 3, the setting
    that won on unseen people in ``docs/methods_report.md``; 1 is plain SIR), ``resampling``, ``known_frames``,
    ``device`` (``"cpu"`` or ``"cuda"``), ``checkpoint_every`` and the annealing's ``survival_rate`` and
    ``layer_diffusion_decay``. The filter starts from the ground truth's first poses (or ``init``, or a bodytrack
    ``InitialPose.txt``).

    ``prior`` and ``likelihood`` are registered names or ready objects; ``likelihood`` None takes
    :func:`default_likelihood` (the keypoints with the edges and silhouettes where the sequence has keypoints,
    else the edges and silhouettes). A prior given by name is built from
    ``models`` (model files, or the models :func:`train` returns) and a likelihood by name; the other
    ``settings`` are their options, each going to the one that declares it (``track(seq, "crbm",
    models=[model], gibbs_steps=10, sharpness=40)``; ``pose-tracker track --prior crbm --help`` lists them).
    Every setting and every declared option, given or default, is recorded in ``result.json`` (the run's settings
    under their own names; ``prior_options``, ``likelihood_options``) and in the checkpoint's fingerprint.
    Random-walk priors take their scale from ``step_std`` or ``train_mocap`` (:func:`build_prior`). ``record``
    chooses what is kept per frame (:mod:`tracker.engine.recording`; add ``"particles"`` and ``"weights"`` to
    keep those); ``on_frame(step, error_mm)`` sees every frame as it is tracked (``error_mm``: the frame's
    absolute MPJPE). ``result.save(dir)`` writes ``result.json`` and ``estimates.npz`` exactly as ``pose-tracker
    track`` does (into a non-empty folder only with ``overwrite=True``, never into the sequence's folder);
    ``result.json`` holds every metric of :data:`tracker.core.metrics.METRICS` and records this call
    (``invocation``: the function and the arguments given) and when it ran (``started``, ``finished``; ISO 8601,
    UTC).

    With ``checkpoint`` (a file path) the filter's state is saved every ``checkpoint_every`` frames and on
    Ctrl-C, which raises :class:`~tracker.app.tracking.TrackingInterrupted` carrying the partial result;
    ``resume=True`` continues from the checkpoint to the result an uninterrupted run gives.
    """
    seq = sequence if isinstance(sequence, Sequence) else load_sequence(sequence)
    given, options = split_settings(settings)
    if likelihood is None:
        likelihood = default_likelihood(seq)
        _refuse_options_of_the_other_default(likelihood, options, seq)
    run = run_settings(given, seq)
    check_frames(seq, run["frames"], run["known_frames"], init)  # before anything is built or loaded
    config = FilterConfig.from_options({o.name: run[o.name] for o in FILTER_OPTIONS})
    rng = make_rng(run["seed"])
    prior_options, likelihood_options = split_options(prior, likelihood, options)
    named_files: tuple[Path, ...] = ()
    if isinstance(prior, str):  # every declared option, checked, with its default: recorded in result.json
        resolved = prior_entry(prior).resolve(prior_options, models)
        prior_options, models, named_files = resolved.options, list(resolved.model_files), resolved.named_files
    if isinstance(likelihood, str):
        likelihood_options = resolve_options(f"likelihood {likelihood}", likelihood_entry(likelihood).options,
                                             likelihood_options)
    if isinstance(prior, str):
        prior_obj = build_prior(prior, seq, models, train_mocap=train_mocap, step_std=step_std,
                                device=run["device"], **prior_options)
    else:
        if models:
            raise InputError("models apply to a prior given by name, not to a prior object")
        prior_obj = prior
    if isinstance(likelihood, str):
        lik_obj = build_likelihood(likelihood, seq, run["views"], device=run["device"], **likelihood_options)
    else:
        lik_obj = likelihood
    recorded = {name: run[name] for name in RECORDED_SETTINGS if name != "frames"}  # frames: run_tracking's
    recorded["seed"] = seed_description(run["seed"])
    settings = {
        "prior": prior if isinstance(prior, str) else prior_obj.name, **recorded,
        "sequence": str(seq.root), "model": seq.model.name,
        "prior_options": prior_options, "prior_settings": prior_obj.settings(),
        "prior_models": [model_name(m) for m in models] + [str(f) for f in named_files],
        "likelihood": likelihood if isinstance(likelihood, str) else lik_obj.name,
        "likelihood_options": likelihood_options, "likelihood_settings": lik_obj.settings(),
    }
    log.debug(f"tracking settings: {settings}")
    try:
        result = run_tracking(seq, prior_obj, lik_obj, config, rng, run["views"], run["frames"],
                              run["known_frames"], init, record, on_frame,
                              None if checkpoint is None else Path(checkpoint), run["checkpoint_every"], resume,
                              fingerprint=settings)
    except TrackingInterrupted as stop:
        if stop.partial is not None:
            stop.partial.settings = settings
        raise
    result.settings = settings
    return result


def _settings_table() -> str:
    """The run's settings as the end of :func:`track`'s docstring lists them."""
    lines = ["Settings (name, default, rule):", ""]
    for o in TRACK_SETTINGS.values():
        rule = o.rule or (f"one of {', '.join(o.choices)}" if o.choices else "")
        unit = f" {o.unit}" if o.unit and o.default is not None else ""
        lines.append(f"    - ``{o.name}`` = ``{o.default!r}``{unit}{'; ' + rule if rule else ''}: {o.help}")
    return "\n".join(lines)


track.__doc__ = (track.__doc__ or "") + "\n    " + _settings_table().replace("\n", "\n    ") + "\n"
