"""What the learned priors' models share: model files (``torch.save`` dictionaries loaded with
``weights_only=True``), their feature normalisers, the check that a model fits the sequence it is asked to track,
and the torch generator each sample draws from. The per-particle parts of the priors are :mod:`priors.parts`."""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, ClassVar, Sequence

import numpy as np

from tracker.core.errors import InputError
from tracker.core.representation import FeatureNormaliser
from tracker.engine.registry import Option

log = logging.getLogger(__name__)

if TYPE_CHECKING:
    import torch


def read_model_file(path, fmt: str, kind: str) -> dict:
    """The dictionary of a learned prior's ``torch.save`` file, loaded with ``weights_only=True``; a missing,
    unreadable or foreign file is an :class:`InputError` naming the file."""
    import zipfile

    import torch

    path = Path(path)
    what = kind if "checkpoint" in kind else f"{kind} model"
    if not path.exists():
        raise InputError(f"{what} file not found", path)
    if path.is_dir():
        raise InputError(f"is a folder, not a {what} file", path)
    try:
        archive = zipfile.is_zipfile(path)
    except OSError as exc:
        raise InputError(f"cannot read the {what} file ({exc.strerror})", path) from None
    if not archive:  # torch.save writes zip archives; anything else (text, a truncated file) is not one of ours
        raise InputError(f"not a {what} file: it is not a (complete) torch archive, which is what "
                         "pose-tracker train writes", path)
    try:
        doc = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a corrupt or foreign archive
        raise InputError(f"damaged or foreign {what} file: torch cannot load it ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0][:120] if str(exc) else 'no reason given'})", path) from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        found = doc.get("format") if isinstance(doc, dict) else None
        held = f"it holds {found!r}" if isinstance(found, str) else "it holds no pose-tracker model"
        raise InputError(f"not a {what} file: {held}, a {what} file has format {fmt!r}", path)
    return doc


@dataclass(kw_only=True)
class ModelData:
    """What every learned prior's model keeps besides its weights: the feature normaliser and the data it was
    trained on (frame rate, body model, pose layout, source clips, per-dof RMS frame-to-frame step in mm or rad).
    A subclass names its kind (``KIND``, for messages)."""

    normaliser: FeatureNormaliser
    fps: float
    body_model: str
    dof_names: list[str]
    sources: list[str]
    pose_step_rms: np.ndarray

    KIND: ClassVar[str] = "learned prior"

    def check_compatible(self, body_model: str, dof_names: Sequence[str], fps: float | None,
                         source: str | Path | None = None) -> None:
        """Refuse a sequence this model was not trained for, saying what differs."""
        check_model_fits(self.KIND, (self.body_model, self.dof_names, self.fps), body_model, dof_names, fps, source)


@dataclass(kw_only=True)
class TrainedModel(ModelData):
    """What the CRBM-family model files keep besides their weights and training settings: :class:`ModelData` and
    how training went. A subclass adds its weights, settings and ``to_document()`` (the model file's dictionary,
    which :meth:`save` writes)."""

    reconstruction_errors: list[float] = field(default_factory=list)
    training_seconds: float = 0.0

    def save(self, path: str | Path, overwrite: bool = False) -> None:
        """The model file at ``path`` (written atomically: never half-written); an existing one is refused
        unless ``overwrite``."""
        torch_save_atomic(self.to_document(), Path(path), overwrite)

    def data_document(self) -> dict:
        """The model file's entries for the fields above (tensors and plain values)."""
        import torch

        return {"fps": float(self.fps), "body_model": self.body_model, "dof_names": list(self.dof_names),
                "sources": list(self.sources), "pose_step_rms": torch.tensor(self.pose_step_rms, dtype=torch.float64),
                "normaliser": normaliser_to_tensors(self.normaliser),
                "reconstruction_errors": [float(e) for e in self.reconstruction_errors],
                "training_seconds": float(self.training_seconds)}

    def fit_note(self) -> str:
        """How the reconstruction error went over training, for one-line summaries (empty if never trained)."""
        errs = self.reconstruction_errors
        return f"reconstruction error {errs[0]:.4f} (epoch 1) -> {errs[-1]:.4f} (epoch {len(errs)}), " if errs else ""


def normaliser_to_tensors(n: FeatureNormaliser) -> dict:
    import torch

    return {"mean": torch.tensor(n.mean), "std": torch.tensor(n.std), "keep": torch.tensor(n.keep),
            "names": list(n.names)}


def normaliser_from_tensors(d: dict, source=None) -> FeatureNormaliser:
    """The normaliser saved by :func:`normaliser_to_tensors`, checked (finite, positive scales, one name per
    feature) by :meth:`FeatureNormaliser.from_arrays`."""
    if not isinstance(d, dict):
        raise InputError("the model file's normaliser is not a dictionary", source)
    try:
        arrays = {"normaliser_mean": d["mean"].numpy(), "normaliser_std": d["std"].numpy(),
                  "normaliser_keep": d["keep"].numpy(), "normaliser_names": list(d["names"])}
    except (KeyError, AttributeError, TypeError) as exc:
        raise InputError(f"the model file's normaliser is malformed ({exc})", source) from None
    return FeatureNormaliser.from_arrays(arrays, source=None if source is None else str(source))


def check_model_fits(kind: str, trained: tuple[str, Sequence[str], float], body_model: str,
                     dof_names: Sequence[str], fps: float | None, source=None) -> None:
    """Refuse to use a learned prior on a sequence it was not trained for, saying what differs.

    ``trained`` is the model's (body model name, pose layout, frame rate).
    """
    t_body, t_dofs, t_fps = trained
    problems = []
    if body_model != t_body:
        problems.append(f"body model {body_model!r} (trained on {t_body!r})")
    elif list(dof_names) != list(t_dofs):
        problems.append("a different pose layout")
    fix = ""
    if fps is not None and abs(fps - t_fps) > 1e-6:
        problems.append(f"{fps:g} fps (trained at {t_fps:g} fps; velocities are per frame)")
        fix = (f": train the model at the sequence's rate (pose-tracker train ... --fps {fps:g}) or render the "
               f"sequence at the model's (pose-tracker synth ... --fps {t_fps:g})")
    if problems:
        raise InputError(f"{kind} model does not fit this sequence: " + "; ".join(problems) + fix, source)
    if fps is None:  # a sequence that states no frame rate (meta.json's fps, groundtruth.npz): said, not assumed
        log.warning(f"the sequence states no frame rate; the {kind} model was trained at {t_fps:g} fps and "
                    "predicts per frame at that rate (give fps in the sequence's meta.json to have it checked)")


def loaded(item, load: Callable, model_type: type, kind: str, **load_args):
    """A prior's model given as a file (read by ``load``) or as the trained ``model_type`` object that ``train``
    returns; anything else is an :class:`InputError`."""
    if isinstance(item, model_type):
        return item
    if isinstance(item, (str, os.PathLike)):
        return load(item, **load_args)
    raise InputError(f"a {kind} model is a model file or a trained {kind} model, got {type(item).__name__}")


def source_of(item) -> Path | None:
    """The file a model came from, for messages (None for a model given in memory)."""
    return Path(item) if isinstance(item, (str, os.PathLike)) else None


def gibbs_steps_option(default: int) -> Option:
    """The ``gibbs_steps`` option of a CRBM-family prior, with its own default."""
    return Option("gibbs_steps", int, default, "alternating Gibbs steps per sample", minimum=1, maximum=10000)


def torch_generator(rng: np.random.Generator, device) -> torch.Generator:
    """A ``torch.Generator`` on ``device`` seeded by one draw from ``rng`` (so the filter's generator fixes every
    torch draw, and a checkpointed ``rng`` state reproduces them)."""
    import torch

    return torch.Generator(device=device).manual_seed(int(rng.integers(2 ** 62)))


#: Highest frame rate (Hz) a learned prior's model file may state.
MAX_MODEL_FPS = 1e5


def checked_model_data(doc: dict, n_features: int, kind: str, source=None
                       ) -> tuple[FeatureNormaliser, float, str, list[str], list[str], np.ndarray]:
    """A learned prior file's normaliser (which must keep the model's ``n_features`` visible units) and its data
    settings (:func:`checked_data_settings`): ``(normaliser, fps, body_model, dof_names, sources,
    pose_step_rms)``."""
    normaliser = normaliser_from_tensors(doc["normaliser"], source)
    if normaliser.n_kept != n_features:
        raise InputError(f"model has {n_features} visible units but its normaliser keeps {normaliser.n_kept}", source)
    return (normaliser, *checked_data_settings(doc, kind, source))


def checked_data_settings(d: dict, kind: str, source=None) -> tuple[float, str, list[str], list[str], np.ndarray]:
    """A learned prior file's data settings ``(fps, body_model, dof_names, sources, pose_step_rms)``, checked:
    fps a number in (0, :data:`MAX_MODEL_FPS`], names text, the per-dof step RMS finite, non-negative, one per
    dof. A missing or malformed one is an :class:`InputError` naming the file and the key."""
    import torch

    try:
        fps, body, dofs, sources, step = (d[k] for k in ("fps", "body_model", "dof_names", "sources", "pose_step_rms"))
    except KeyError as exc:
        raise InputError(f"{kind} model file lacks {exc.args[0]!r}", source) from None
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0 < fps <= MAX_MODEL_FPS:
        raise InputError(f"{kind} model file's fps must be a number in (0, {MAX_MODEL_FPS:g}] Hz, got {fps!r}", source)
    for key, names in (("body_model", [body]), ("dof_names", dofs), ("sources", sources)):
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise InputError(f"{kind} model file's {key} must be {'text' if key == 'body_model' else 'a list of text'}",
                             source)
    if not isinstance(step, torch.Tensor) or tuple(step.shape) != (len(dofs),) or not step.is_floating_point() \
            or not torch.all(torch.isfinite(step)) or torch.any(step < 0):
        raise InputError(f"{kind} model file's pose_step_rms must be finite, non-negative, one per pose number", source)
    return float(fps), body, list(dofs), list(sources), step.numpy()


def epoch_checkpoint(checkpoint: tuple[Callable[[object, dict], None], int] | None, model: object,
                     training_state: Callable[[int], dict], done: int, epochs: int) -> dict | None:
    """After ``done`` of ``epochs`` epochs of a training that checkpoints (``checkpoint = (save, every)``, or None):
    the training state ``training_state(done)``, which ``save(model, state)`` also writes every ``every`` epochs
    (0: never) but the last; None without checkpointing. The caller keeps it for an interrupt to save."""
    if checkpoint is None:
        return None
    state = training_state(done)
    save, every = checkpoint
    if every and done % every == 0 and done < epochs:
        save(model, state)
    return state


def torch_save_atomic(doc: dict, path: Path, overwrite: bool = True) -> None:
    """``torch.save(doc, path)`` through a temporary file beside ``path`` and an atomic rename, so ``path`` is
    never half-written (a training checkpoint interrupted while saving keeps the one before). The document is
    serialised in memory first, so a failed write (no space left, read-only, no permission) is the
    :class:`OSError` naming its cause that Python's own writes raise, not torch's bare ``RuntimeError``.
    Without ``overwrite`` an existing non-empty ``path`` is refused (a model file the user did not ask to
    replace)."""
    import io

    import torch

    if not overwrite and path.is_file() and path.stat().st_size > 0:
        raise InputError("the model file exists (pass overwrite=True to replace it)", path)
    buffer = io.BytesIO()
    torch.save(doc, buffer)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_bytes(buffer.getbuffer())
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


def check_weights(weights: dict, expected: dict, kind: str, sizes: str, source=None) -> None:
    """Refuse a model file whose tensors ``weights[k]`` lack the shapes ``expected[k]`` (``sizes`` says what the
    shapes follow from, e.g. "order 3 with 40 visible and 150 hidden units") or hold NaN or infinite values."""
    import torch

    for k, shape in expected.items():
        if tuple(weights[k].shape) != tuple(shape):
            raise InputError(f"{kind} {k} has shape {tuple(weights[k].shape)}; {sizes} needs {tuple(shape)}", source)
        if not torch.all(torch.isfinite(weights[k])):
            raise InputError(f"{kind} {k} contains NaN or infinite values", source)
