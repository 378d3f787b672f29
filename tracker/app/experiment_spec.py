"""An experiment as validated data: its sequences, priors (with the model files and trainings they take) and
likelihood variants, and the grid's settings. :func:`tracker.app.experiment.load_experiment` reads one from a file
(whose format that module describes); :mod:`tracker.app.run_grid` expands it into runs; :mod:`tracker.app.compare`
prepares and runs them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class SequenceSpec:
    name: str
    path: Path | None = None          # an existing folder
    mocap: Path | None = None         # or a clip to render
    skeleton: Path | None = None
    synth: dict = field(default_factory=dict)
    #: A folder's first poses (a poses .npz, as ``initialise`` writes it; ``track --init``).
    init: Path | None = None
    #: Another method's reconstruction of the folder (TRC), and its frame of the runs' frame 0 (None: the
    #: sequence's ``first_video_frame``, else 0).
    reference: Path | None = None
    reference_offset: int | None = None


@dataclass(frozen=True)
class ClipSpec:
    """A training clip: a mocap file, optionally only ``frames`` frames from ``start`` (at the experiment's
    frame rate), and the joint map of a file whose joint names are not recognised (as read: body point -> the
    file's joint name)."""

    path: Path
    start: int = 0
    frames: int | None = None
    joint_map: dict | None = None


@dataclass(frozen=True)
class TrainSpec:
    """A model the runner trains: clips, skeletons, training options and seed, and the prior it trains (None:
    the entry's own; a mixture's component names its prior)."""

    mocap: tuple[ClipSpec, ...]
    skeletons: tuple[Path, ...] | None
    options: dict
    seed: int
    prior: str | None = None


@dataclass(frozen=True)
class PriorSpec:
    label: str
    name: str
    options: dict
    models: tuple[Path, ...]
    train: tuple[TrainSpec, ...]
    train_mocap: tuple[ClipSpec, ...] | None
    #: For one of the rows a ``train_seeds`` entry expands into: the entry's own label (the group's) and this
    #: row's training seed; None for an ordinary entry.
    replicate_of: str | None = None
    training_seed: int | None = None
    #: The model files and trainings in the order the prior takes them, where it is not ``models`` then ``train``
    #: (a mixture's ``[[prior.components]]``, each taking its own); empty otherwise.
    sources: tuple[Path | TrainSpec, ...] = ()

    def model_sources(self) -> tuple[Path | TrainSpec, ...]:
        """The prior's model files (given, or trained by the runner) in the order its builder takes them."""
        return self.sources or (*self.models, *self.train)


@dataclass(frozen=True)
class LikelihoodSpec:
    label: str
    name: str
    options: dict


@dataclass
class Experiment:
    """A validated experiment (its file: :mod:`tracker.app.experiment`)."""

    path: Path
    description: str
    seed: int
    seeds: int
    fps: float
    baseline: str
    paired: str
    tracking: dict[str, list]
    sequences: list[SequenceSpec]
    priors: list[PriorSpec]
    likelihoods: list[LikelihoodSpec]
    #: The folder the data paths were resolved against (None: the file declares no data root).
    data_root: Path | None = None
