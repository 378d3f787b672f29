"""An experiment's runs: the grid of sequences x priors x likelihood variants x view sets x particle counts x
annealing layers x seeds expanded into :class:`RunSpec` entries, each self-contained (a worker of any backend,
:mod:`tracker.app.backends`, executes it) and named by the hash of everything that determines its numbers, and
each seed index's generator seed (:func:`run_seed`).
"""
from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from data_tools.io.fingerprints import config_hash, file_hash
from tracker.app.experiment_spec import Experiment, LikelihoodSpec, PriorSpec


def run_seed(master_seed: int, index: int) -> np.random.SeedSequence:
    """The generator seed of seed index ``index``: the same for every prior and sequence (paired runs), and
    independent of which worker runs it or when (it equals ``SeedSequence(master_seed).spawn(n)[index]``)."""
    return np.random.SeedSequence(master_seed, spawn_key=(index,))


@dataclass(frozen=True)
class RunSpec:
    """One tracking run, self-contained so that any worker (process, Dask or Ray) can execute it."""

    key: str                     # hash of everything that determines the numbers: the run folder's name
    sequence: str                # sequence name (table column)
    sequence_path: str
    row: str                     # table row label
    prior: str
    prior_options: dict
    models: tuple[str, ...]
    step_std: tuple[float, ...] | None  # the random-walk scale (None: the default training clips)
    likelihood: str
    likelihood_options: dict
    views: tuple[int, ...] | None
    particles: int
    annealing_layers: int
    frames: int | None
    known_frames: int
    resampling: str
    seed_index: int
    seed_entropy: int
    out: str                     # the experiment's runs/ folder
    threads: int = 1
    #: The filter's other settings (``ess_threshold``, ``survival_rate``, ``layer_diffusion_decay``).
    filter_options: dict = field(default_factory=dict)
    #: The sequence's first poses (a poses .npz), where the experiment gives them (``init``).
    init: str | None = None

    def as_dict(self) -> dict:
        return asdict(self)

    def settings(self) -> dict[str, Any]:
        """The run's settings by their names in :mod:`tracker.app.schema` (the keywords of ``tracker.track``),
        its seed aside (:func:`run_seed`)."""
        return {"particles": self.particles, "annealing_layers": self.annealing_layers, "views": self.views,
                "frames": self.frames, "known_frames": self.known_frames, "resampling": self.resampling,
                **self.filter_options}


def row_label(prior: PriorSpec, likelihood: LikelihoodSpec, views, particles: int, layers: int,
              exp: Experiment) -> str:
    """The table row of a configuration: the prior's label, plus each grid axis that has several values."""
    parts = [prior.label]
    if len(exp.likelihoods) > 1:
        parts.append(likelihood.label)
    if len(exp.tracking["views"]) > 1:
        parts.append(f"views {','.join(map(str, views))}" if views else "all views")
    if len(exp.tracking["particles"]) > 1:
        parts.append(f"{particles} particle{'s' if particles != 1 else ''}")
    if len(exp.tracking["annealing_layers"]) > 1:
        parts.append(f"{layers} layer{'s' if layers != 1 else ''}")
    return ", ".join(parts)


def expand_runs(exp: Experiment, sequence_paths: dict[str, Path], sequence_hashes: dict[str, str],
                model_paths: dict[str, tuple[Path, ...]], scales: dict[str, np.ndarray | None], out: Path,
                version: str) -> list[RunSpec]:
    """Every run of the grid, each with its content hash as key."""
    runs = []
    model_hashes = {label: [file_hash(m) for m in paths] for label, paths in model_paths.items()}
    for seq, prior, lik, views, particles, layers in itertools.product(
            exp.sequences, exp.priors, exp.likelihoods, exp.tracking["views"], exp.tracking["particles"],
            exp.tracking["annealing_layers"]):
        scale = scales.get(prior.label)
        step_std = None if scale is None else tuple(float(x) for x in scale)
        for i in range(exp.seeds):
            identity = {
                "sequence": sequence_hashes[seq.name], "prior": prior.name, "prior_options": prior.options,
                "models": model_hashes[prior.label],
                "step_std": None if step_std is None else [round(x, 12) for x in step_std],
                "likelihood": lik.name, "likelihood_options": lik.options, "views": views,
                "particles": particles, "annealing_layers": layers, "frames": exp.tracking["frames"],
                "known_frames": exp.tracking["known_frames"], "resampling": exp.tracking["resampling"],
                "seed": [exp.seed, i], "version": version, **_filter_options(exp),
                **({} if seq.init is None else {"init": file_hash(seq.init)}),
            }
            runs.append(RunSpec(
                key=config_hash(identity), sequence=seq.name, sequence_path=str(sequence_paths[seq.name]),
                row=row_label(prior, lik, views, particles, layers, exp), prior=prior.name,
                prior_options=prior.options, models=tuple(str(m) for m in model_paths[prior.label]),
                step_std=step_std, likelihood=lik.name, likelihood_options=lik.options,
                views=None if views is None else tuple(views), particles=particles, annealing_layers=layers,
                frames=exp.tracking["frames"], known_frames=exp.tracking["known_frames"],
                resampling=exp.tracking["resampling"], seed_index=i, seed_entropy=exp.seed, out=str(out),
                filter_options=_filter_options(exp), init=None if seq.init is None else str(seq.init)))
    return runs


def _filter_options(exp: Experiment) -> dict[str, Any]:
    """The ``[tracking]`` settings of the filter that are not grid axes or a run's frames (a run's
    :attr:`RunSpec.filter_options`)."""
    return {k: exp.tracking[k] for k in ("ess_threshold", "survival_rate", "layer_diffusion_decay")}
