"""What the learned priors share: model files (``torch.save`` dictionaries loaded with ``weights_only=True``),
their feature normalisers, the check that a model fits the sequence it is asked to track, ground-plane
diffusion, and the torch generator each sample draws from."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, Sequence

import numpy as np

from tracker.core.errors import InputError
from tracker.core.representation import STEP_FEATURES, FeatureNormaliser, poses_to_invariant
from tracker.core.rotations import continuous_exp_maps, elementary_rotation, exp_map_to_matrix, matrix_to_exp_map
from tracker.engine.registry import Option

if TYPE_CHECKING:
    import torch


def read_model_file(path, fmt: str, kind: str) -> dict:
    """The dictionary of a learned prior's ``torch.save`` file, loaded with ``weights_only=True``; a missing,
    unreadable or foreign file is an :class:`InputError` naming the file."""
    import torch

    path = Path(path)
    try:
        doc = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise InputError("model file not found", path) from None
    except Exception as exc:  # torch raises many types for a corrupt or foreign file
        raise InputError(f"cannot read model file ({type(exc).__name__}: {str(exc)[:120]})", path) from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        raise InputError(f"not a {kind} model file (expected format {fmt!r})", path)
    return doc


@dataclass(kw_only=True)
class TrainedModel:
    """What the CRBM-family model files keep besides their weights and training settings: the feature normaliser,
    the data they were trained on (frame rate, body model, pose layout, source clips, per-dof RMS frame-to-frame
    step in mm or rad, the playback speeds of ``train --time-warp``) and how training went. A subclass names its
    kind (``KIND``, for messages) and adds its weights, settings and ``to_document()`` (the model file's
    dictionary, which :meth:`save` writes)."""

    normaliser: FeatureNormaliser
    fps: float
    body_model: str
    dof_names: list[str]
    sources: list[str]
    pose_step_rms: np.ndarray
    reconstruction_errors: list[float] = field(default_factory=list)
    training_seconds: float = 0.0
    #: Playback speeds the training clips were replayed at (``train --time-warp``; [1.0]: as given).
    time_warp: list[float] = field(default_factory=lambda: [1.0])

    KIND: ClassVar[str] = "learned prior"

    def save(self, path: str | Path) -> None:
        """The model file at ``path`` (written atomically: never half-written)."""
        torch_save_atomic(self.to_document(), Path(path))

    def data_document(self) -> dict:
        """The model file's entries for the fields above (tensors and plain values)."""
        import torch

        return {"fps": float(self.fps), "body_model": self.body_model, "dof_names": list(self.dof_names),
                "sources": list(self.sources), "pose_step_rms": torch.tensor(self.pose_step_rms, dtype=torch.float64),
                "normaliser": normaliser_to_tensors(self.normaliser),
                "reconstruction_errors": [float(e) for e in self.reconstruction_errors],
                "training_seconds": float(self.training_seconds), "time_warp": [float(s) for s in self.time_warp]}

    def fit_note(self) -> str:
        """How the reconstruction error went over training, for one-line summaries (empty if never trained)."""
        errs = self.reconstruction_errors
        return f"reconstruction error {errs[0]:.4f} (epoch 1) -> {errs[-1]:.4f} (epoch {len(errs)}), " if errs else ""

    def check_compatible(self, body_model: str, dof_names: Sequence[str], fps: float | None,
                         source: str | Path | None = None) -> None:
        """Refuse a sequence this model was not trained for, saying what differs."""
        check_model_fits(self.KIND, (self.body_model, self.dof_names, self.fps), body_model, dof_names, fps, source)


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
    if fps is not None and abs(fps - t_fps) > 1e-6:
        problems.append(f"{fps:g} fps (trained at {t_fps:g} fps; velocities are per frame)")
    if problems:
        raise InputError(f"{kind} model does not fit this sequence: " + "; ".join(problems), source)


#: Default ground-plane diffusion (mm per frame) of learned-prior samples. A learned prior predicts body-centred
#: motion; the ground position integrates its velocities, and a walker slightly faster or slower than the
#: training walks drifts away from particles that all move alike. Chosen for the CRBM on a validation render
#: (07_01 tracked with CRBMs trained on 07_02, 07_09, 07_10; 1000 particles, 4 views, 2 seeds): 0 mm gave
#: 41-71 mm error, 3 and 6 mm 16-18 mm, 12 mm 17-20 mm; Gaussian noise on all normalised features instead made
#: it worse. The GPDM prior uses the same value (not tuned separately).
ROOT_NOISE_MM = 5.0


def add_ground_diffusion(poses: np.ndarray, std_mm: float, rng: np.random.Generator) -> np.ndarray:
    """``poses`` ``P x D`` with Gaussian noise of ``std_mm`` added to the root's ground position (x, y), in place;
    lets the likelihood correct the drift of integrated velocities."""
    if std_mm > 0:
        poses[:, :2] += std_mm * rng.standard_normal((len(poses), 2))
    return poses


def add_heading_diffusion(poses: np.ndarray, previous: np.ndarray, std_rad: float,
                          rng: np.random.Generator) -> np.ndarray:
    """``poses`` ``P x D`` with each root turned about the vertical by Gaussian noise of ``std_rad``, in place
    (the root's exp map stays on the branch nearest ``previous``'s). A learned prior integrates its heading
    from predicted yaw rates; without noise on the heading the likelihood cannot correct a heading that has
    drifted (the ground-plane diffusion only moves the position)."""
    if std_rad > 0:
        turn = elementary_rotation("z", std_rad * rng.standard_normal(len(poses)))
        turned = matrix_to_exp_map(turn @ exp_map_to_matrix(poses[:, 3:6]))
        poses[:, 3:6] = continuous_exp_maps(np.stack([previous[:, 3:6], turned], axis=-2), time_axis=-2)[:, 1]
    return poses


def mix_in_random_walk(poses: np.ndarray, last: np.ndarray, std: np.ndarray, fraction: float,
                       rng: np.random.Generator) -> np.ndarray:
    """The robust option of the learned priors: each particle's sample ``P x D`` is replaced, with probability
    ``fraction``, by a zero-velocity random-walk step from its last pose (``last`` ``P x D``, per-dof ``std``),
    in place. Returns the mask ``(P,)`` of replaced particles, whose pending step the prior must then take
    from the move they actually made (:func:`steps_taken`). With ``fraction`` 0 nothing is drawn."""
    if fraction <= 0:
        return np.zeros(len(poses), bool)
    mask = rng.random(len(poses)) < fraction
    n = int(mask.sum())
    if n:
        poses[mask] = last[mask] + rng.standard_normal((n, poses.shape[1])) * std
    return mask


#: Most of each frame's samples the adaptive robust option gives to the random walk (see :func:`robust_share`).
ROBUST_CAP = 0.5


def robust_share(walked: np.ndarray | None, floor: float, adaptive: bool) -> float:
    """The fraction of this frame's samples the robust option draws from the zero-velocity random walk.

    Fixed at ``floor`` unless ``adaptive``; then it follows the posterior: ``walked`` ``(P,)`` flags the
    particles whose latest sample came from the random walk, *after* resampling, so its mean is the share of
    the posterior mass that the random walk earned on the last frame (the mixture-weight update of population
    Monte Carlo, Douc et al. 2007), kept within ``[floor, ROBUST_CAP]``. The prior sees the particles, not
    their weights, so the share is the posterior's only when the filter resampled after the last frame (it did
    on every frame of the measured runs: their mean effective sample size stayed far below the resampling
    threshold); after a frame without resampling it repeats the last proposal's share. When the person does what
    the model learned, the learned samples win and the share falls to ``floor``; at a start, a stop or a change
    of pace the random walk wins and the share grows, without a setting tuned per sequence."""
    if not adaptive or walked is None or len(walked) == 0:
        return floor
    return float(min(max(floor, np.mean(walked)), max(floor, ROBUST_CAP)))


#: The options of the learned priors for people and motion their model did not learn (the CRBM and GPDM
#: priors declare them alike): a share of random-walk samples, fixed or following the posterior, and a pace.
UNLEARNED_MOTION_OPTIONS = (
    Option("robust_fraction", float, 0.0,
           "fraction of each frame's samples drawn from the zero-velocity random walk instead, so motion the model "
           "did not learn (a start, a stop, a run) stays trackable (default 0); with robust_adaptive, the least "
           "fraction", minimum=0.0, maximum=1.0),
    Option("robust_adaptive", bool, False,
           "let the random walk's share follow the posterior mass its samples earned on the last frame, between "
           f"robust_fraction and {ROBUST_CAP} (default off)"),
    Option("pace_spread", float, None, "std of each particle's log pace at the start: the log factor between its "
                                       "ground steps and the model's (default 0: the model's pace), or, for a CRBM "
                                       "trained with --pace-input, around the known frames' pace (default 0.3)",
           minimum=0.0, maximum=3.0),
    Option("pace_drift", float, None, "std of the change of each particle's log pace per frame (default 0; 0.05 "
                                      "for a CRBM trained with --pace-input)", minimum=0.0, maximum=1.0),
)


#: The sampling options the CRBM-family priors (CRBM, deep CRBM, FCRBM) share.
ROOT_NOISE_OPTION = Option("root_noise", float, ROOT_NOISE_MM,
                           f"ground-plane diffusion of each sample in mm (default {ROOT_NOISE_MM:g})",
                           minimum=0.0, maximum=1000.0)
HEADING_NOISE_OPTION = Option("heading_noise", float, 0.0,
                              "diffusion of each sample's heading in rad per frame, so that the likelihood can "
                              "correct an integrated heading (default 0)", minimum=0.0, maximum=float(np.pi))


def gibbs_steps_option(default: int) -> Option:
    """The ``gibbs_steps`` option of a CRBM-family prior, with its own default."""
    return Option("gibbs_steps", int, default, f"alternating Gibbs steps per sample (default {default})", minimum=1,
                  maximum=10000)


#: The learned priors' option to take each particle's ground step from its own motion (:func:`persist_ground_step`).
GROUND_VELOCITY_OPTION = Option(
    "ground_velocity_noise", float, None,
    "let each particle keep its own ground step from frame to frame (constant velocity in the body's frame), "
    "changed by Gaussian noise of this std in mm/frame per frame, instead of the step the model predicts; the model "
    "still drives the height, orientation, heading rate and joints, and a model with a pace input is told the "
    "particle's own ground speed (default: off, the model's steps)", minimum=0.0, maximum=1000.0)
#: How fast each particle's own ground velocity decays toward standing still (:func:`persist_ground_step`).
GROUND_VELOCITY_PULL_OPTION = Option(
    "ground_velocity_pull", float, 0.0,
    "with --ground-velocity-noise, the fraction of each particle's own ground velocity lost per frame, so that a "
    "velocity the images do not keep selecting decays toward standing still instead of drifting (an "
    "Ornstein-Uhlenbeck velocity; default 0, constant velocity)", minimum=0.0, maximum=1.0)


#: The learned priors' option to give each particle its own root-height offset (mm, the person's root height minus
#: the heights the model learned): a learned prior predicts the root heights of the people it was trained on, and
#: a shorter or crouching person (issue 13's folds 91 and 131) is followed only if the particles carry heights
#: that the likelihood can select.
HEIGHT_SPREAD_HELP = ("give each particle its own offset between the person's root height and the heights the model "
                      "learned, Gaussian with this std in mm at the start, so that the images select the height of "
                      "a shorter, taller or crouching person")
HEIGHT_SPREAD_OPTION = Option("height_spread", float, 0.0, f"{HEIGHT_SPREAD_HELP} (default 0: the model's heights)",
                              minimum=0.0, maximum=1000.0)
#: How fast each particle's root-height offset drifts (:func:`gaussian_drift`).
HEIGHT_DRIFT_OPTION = Option(
    "height_drift", float, 0.0,
    "std in mm per frame of the random walk of each particle's root-height offset, so that it can follow a person "
    "who crouches or straightens up (default 0: the offset keeps its start value)", minimum=0.0, maximum=100.0)


def checked_height_offset(spread: float, drift: float) -> tuple[float, float]:
    """The height-offset settings as ``(spread, drift)`` (mm, mm/frame), within the bounds of
    :data:`HEIGHT_SPREAD_OPTION` and :data:`HEIGHT_DRIFT_OPTION`; a value outside them (or not a number) is an
    :class:`InputError`."""
    for option, value, unit in ((HEIGHT_SPREAD_OPTION, spread, "mm"), (HEIGHT_DRIFT_OPTION, drift, "mm per frame")):
        if not option.minimum <= value <= option.maximum:
            raise InputError(f"height {option.name.split('_')[1]} must be between {option.minimum:g} and "
                             f"{option.maximum:g} {unit}, got {value}")
    return float(spread), float(drift)


class HeightOffsets:
    """What a learned prior whose particles may carry their own root-height offset (mm; the person's root height
    minus the model's, :data:`HEIGHT_SPREAD_OPTION`) shares: the settings, whether they are on, the offsets at the
    start and their posterior mean. The prior adds the offsets to the heights its model predicts."""

    #: The std (mm) of each particle's root-height offset at the start (with ``height_drift`` both 0: no offset).
    height_spread: float = 0.0
    #: The std (mm/frame) of each frame's random-walk step of the root-height offset.
    height_drift: float = 0.0

    def set_height_offsets(self, spread: float, drift: float) -> None:
        """The settings, checked by :func:`checked_height_offset`."""
        self.height_spread, self.height_drift = checked_height_offset(spread, drift)

    @property
    def height_offsets(self) -> bool:
        """Whether each particle carries its own root-height offset (``height_spread`` or ``height_drift``)."""
        return self.height_spread > 0 or self.height_drift > 0

    def start_height_offsets(self, n_particles: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """The state entry ``height_offset`` ``(P,)`` at the start (Gaussian, ``height_spread``), or none."""
        return {"height_offset": gaussian_start(n_particles, self.height_spread, rng)} if self.height_offsets else {}

    @staticmethod
    def mean_height_offset(state: dict, weights: np.ndarray) -> float:
        """The posterior mean offset (mm) under the normalised ``weights`` ``(P,)``."""
        return float(np.sum(weights * state["height_offset"]))


def checked_fraction_per_frame(name: str, value: float) -> float:
    """``value`` as a float when it is a fraction per frame in [0, 1] (a gain or a pull); otherwise an
    :class:`InputError` naming the setting ``name``."""
    if not 0 <= value <= 1:
        raise InputError(f"{name} must be a fraction per frame in [0, 1], got {value}")
    return float(value)


def checked_ground_velocity(noise: float | None, pull: float,
                            pace_jump: float = 0.0) -> tuple[float | None, float]:
    """The settings of :func:`persist_ground_step` as ``(noise, pull)``: ``noise`` (mm/frame per frame, None for
    the model's own steps) and ``pull`` (fraction per frame); bad values, a pull without an own velocity, or a
    pace jump (a pace the particle's velocity would not follow) are an :class:`InputError`."""
    if noise is not None:
        if not noise >= 0:
            raise InputError(f"ground velocity noise must be a non-negative number of mm per frame per frame, got "
                             f"{noise}")
        if pace_jump > 0:
            raise InputError("pace jump draws a pace the particle's ground velocity would not follow; with ground "
                             "velocity noise the pace is the particle's own ground speed")
        noise = float(noise)
    pull = checked_fraction_per_frame("ground velocity pull", pull)
    if pull > 0 and noise is None:
        raise InputError("ground velocity pull acts on each particle's own ground velocity: give it with ground "
                         "velocity noise")
    return noise, float(pull)


def persist_ground_step(step: np.ndarray, std: float, rng: np.random.Generator, pull: float = 0.0) -> np.ndarray:
    """The forward and lateral ground step ``P x 2`` (mm/frame, the first two of
    :data:`~tracker.core.representation.STEP_FEATURES`) each particle takes out of its next pose: the step ``step``
    ``P x 2+`` it takes now, shrunk by the fraction ``pull`` toward zero, plus Gaussian noise of ``std`` (nothing
    drawn when 0). A learned prior's integrated steps carry the training walkers' pace and leave a slower or faster
    person behind (issue 13's folds 91 and 131); a step that persists follows whatever speed the likelihood has
    selected, as the baseline's random walk does, while the model keeps the body's dynamics. Without a pull the
    velocity is a random walk, which drifts where the images do not constrain it (depth, with one view) and walks
    on when the person stops; with one it is an Ornstein-Uhlenbeck process whose stationary std is
    ``std / sqrt(1 - (1 - pull)^2)`` about standing still."""
    out = (1.0 - pull) * np.array(step[:, :2], float)
    if std > 0:
        out += std * rng.standard_normal(out.shape)
    return out


def gaussian_start(n_particles: int, std: float, rng: np.random.Generator) -> np.ndarray:
    """Each particle's initial value ``(P,)`` of a per-particle latent that starts at 0, Gaussian with std
    ``std`` (nothing drawn when 0): the log pace (the log of the factor between the person's ground steps and the
    steps the learned model would take) and the root-height offset (mm, the person's root height minus the
    model's)."""
    if std <= 0:
        return np.zeros(n_particles)
    return std * rng.standard_normal(n_particles)


def gaussian_drift(values: np.ndarray, std: float, rng: np.random.Generator) -> np.ndarray:
    """Per-particle latents ``(P,)`` (a log pace, a root-height offset) after one frame's random walk of std
    ``std`` (nothing drawn when 0)."""
    if std <= 0:
        return values
    return values + std * rng.standard_normal(len(values))


def scale_ground_steps(features: np.ndarray, factor: np.ndarray) -> np.ndarray:
    """Invariant features ``P x ... x K`` with the ground-plane steps (forward and lateral velocity) of every
    frame multiplied by ``factor`` ``(P,)``, in place. A learned prior conditions on its history divided by a
    particle's pace and multiplies its prediction by it, so one model walks people of other speeds and stride
    lengths; the heading rate and the joints are left to the model."""
    shape = (len(factor),) + (1,) * (features.ndim - 1)
    features[..., :2] *= factor.reshape(shape)
    return features


def shift_height(features: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Invariant features ``P x ... x K`` with the root height (mm) of every frame moved by ``offset`` ``(P,)``
    mm, in place. The CRBM predicts the absolute root height of the people it was trained on; a shorter or
    taller person's heights, moved to the training subjects' mean before the model sees them and back after,
    keep the person's own height (``relative_height``); a model trained on heights above standing is moved by the
    person's standing root height instead (:meth:`priors.crbm.CRBMPrior.height_to_model`)."""
    shape = (len(offset),) + (1,) * (features.ndim - 1)
    features[..., 2:3] += np.asarray(offset, float).reshape(shape)
    return features


def steps_taken(last: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """The root steps ``n x 3`` (:data:`~tracker.core.representation.STEP_FEATURES`) from ``last`` to ``poses``
    (each ``n x D``)."""
    if len(poses) == 0:
        return np.zeros((0, len(STEP_FEATURES)))
    return poses_to_invariant(np.stack([last, poses], axis=1))[:, 0, list(STEP_FEATURES)]


def torch_generator(rng: np.random.Generator, device) -> torch.Generator:
    """A ``torch.Generator`` on ``device`` seeded by one draw from ``rng`` (so the filter's generator fixes every
    torch draw, and a checkpointed ``rng`` state reproduces them)."""
    import torch

    return torch.Generator(device=device).manual_seed(int(rng.integers(2 ** 62)))


#: Highest frame rate (Hz) a learned prior's model file may state.
MAX_MODEL_FPS = 1e5


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


def checked_time_warp(value, kind: str, source=None) -> list[float]:
    """A model file's ``time_warp`` (the playback speeds its training clips were replayed at; files written
    before the option have none: ``[1.0]``), checked like the option; a bad one is an :class:`InputError`
    naming the file."""
    from tracker.core.timewarp import parse_speeds

    if value is None:
        return [1.0]
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                       for v in value):
        raise InputError(f"{kind} model file's time_warp must be a list of playback speeds, got {value!r}", source)
    try:
        return list(parse_speeds(list(value), f"{kind} model file's time_warp"))
    except InputError as exc:
        raise InputError(exc.reason, source) from None


def time_warp_note(speeds: Sequence[float]) -> str:
    """The part of a model's one-line summary that says at which speeds its clips were replayed ("" for 1)."""
    speeds = list(speeds)
    return "" if speeds == [1.0] else f", clips replayed at speeds {', '.join(f'{s:g}' for s in speeds)}"


def torch_save_atomic(doc: dict, path: Path) -> None:
    """``torch.save(doc, path)`` through a temporary file beside ``path`` and an atomic rename, so ``path`` is
    never half-written (a training checkpoint interrupted while saving keeps the one before)."""
    import torch

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        torch.save(doc, tmp)
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
