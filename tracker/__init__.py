"""3D human pose tracking with learned dynamical priors.

The public API (``import tracker``)::

    tracker.load_sequence, tracker.load_clip, tracker.synthesize    data
    tracker.load_clips("walks/*.bvh")                               a corpus: files, folders, patterns
    tracker.sample_walks()                                          the shipped CMU walks (skeleton, clips)
    tracker.build_prior, tracker.build_likelihood, tracker.train    models
    tracker.train_into(model_file, ...)                            a training stopped and continued
    tracker.track -> TrackingResult (.save writes result.json)     tracking
    tracker.track_into(out, ...), tracker.resume_tracking(out)      a run in a folder, stopped and continued
    tracker.show(seq, frame=0, poses=..., out="f.png", video=...)   the body model drawn over the views
    tracker.compare(experiment.toml, out, jobs=2)                  experiments (tables, plots)
    tracker.fetch(["07_01"], data_root=DIR), fetch(experiment=...)  CMU trials downloaded and checked
    tracker.set_threads(n)                                         threads for BLAS, OpenCV, torch
    tracker.marker_error, tracker.sequence_error, tracker.summarize_runs
    tracker.register_prior, tracker.register_likelihood, tracker.Option,
    tracker.MotionPrior, tracker.Likelihood, tracker.FrameLikelihood, tracker.Frame   extending
    tracker.available_priors(), tracker.available_likelihoods()
    tracker.InputError                                              every refusal of bad input

Layers (checked by import-linter, see pyproject.toml): ``tracker.core``
(geometry) <- ``tracker.engine`` (model contract, filter, registries) <-
``priors``, ``likelihoods``, ``data_tools`` (plugins and file formats) <-
``tracker.app`` (this API, visualisation, the command line). Names are
resolved on first use, so importing ``tracker.core`` from a plugin does not
pull in the application layer.

Conventions (docs/conventions.md): world z up, millimetres, radians, images
H x W with (x, y) pixel coordinates, batches on the leading axis.
"""
import importlib as _importlib
import os as _os

# OpenMP threads (torch's and MKL's) that finish a parallel region spin, waiting for the next, unless told to
# sleep; on a machine where other processes run, the spinning threads take the cores the work needs. Measured
# on a busy 2-core machine, sampling a CRBM for 1000 particles with 2 torch threads: median 122-126 ms (worst
# calls 1.9 s) spinning against 51-54 ms passive, 34-49 ms with one thread. Set before torch is imported (the
# OpenMP runtime reads it when it loads); an explicit setting of the caller's wins.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

__version__ = "0.25.0"

_EXPORTS = {
    "load_sequence": "tracker.app.api", "load_clip": "tracker.app.api", "load_clips": "tracker.app.api",
    "synthesize": "tracker.app.api",
    "build_prior": "tracker.app.api", "build_likelihood": "tracker.app.api", "train": "tracker.app.api",
    "track": "tracker.app.api", "track_into": "tracker.app.run_folder", "resume_tracking": "tracker.app.run_folder",
    "train_into": "tracker.app.train_file", "available_priors": "tracker.app.api", "available_likelihoods": "tracker.app.api",
    "random_walk_scale": "tracker.app.api", "show": "tracker.app.api",
    "TrackingResult": "tracker.app.tracking", "compare": "tracker.app.compare",
    "load_experiment": "tracker.app.experiment", "fetch": "tracker.app.fetching", "set_threads": "tracker.app.threads",
    "SynthConfig": "data_tools.synthesis.synth_settings", "sample_walks": "data_tools.samples",
    "marker_error": "tracker.core.metrics", "sequence_error": "tracker.core.metrics",
    "summarize_runs": "tracker.core.metrics",
    "register_prior": "tracker.engine.registry", "register_likelihood": "tracker.engine.registry",
    "Option": "tracker.engine.registry", "PriorContext": "tracker.engine.registry",
    "LikelihoodContext": "tracker.engine.registry", "TrainingData": "tracker.engine.registry",
    "MotionPrior": "tracker.engine.prior", "Likelihood": "tracker.engine.likelihood",
    "FrameLikelihood": "tracker.engine.likelihood", "Frame": "tracker.engine.likelihood",
    "FrameStep": "tracker.engine.recording", "FilterConfig": "tracker.engine.filter",
    "ParticleFilter": "tracker.engine.filter",
    "InputError": "tracker.core.errors",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(_importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'tracker' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The API only (and ``__version__``), not the names this module uses itself."""
    return sorted([*__all__, "__version__"])
