"""The motion-prior interface the particle filter relies on (DESIGN.md "Particle filter").

A prior of order ``N`` samples the next pose of every particle from that
particle's own last ``N`` poses (the augmented state of Isard & Blake), plus
any per-particle state of its own (e.g. GPDM latent coordinates). Shapes:
histories ``P x N x D`` (oldest first), poses ``P x D``; per-particle state is
``None``, an array with ``P`` on its leading axis, or a dict of such arrays.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from tracker.core.errors import InputError
from tracker.core.representation import FeatureNormaliser

PriorState = Any


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


def normaliser_to_tensors(n: FeatureNormaliser) -> dict:
    import torch

    return {"mean": torch.tensor(n.mean), "std": torch.tensor(n.std), "keep": torch.tensor(n.keep),
            "names": list(n.names)}


def normaliser_from_tensors(d: dict) -> FeatureNormaliser:
    return FeatureNormaliser(d["mean"].numpy(), d["std"].numpy(), d["keep"].numpy().astype(bool), list(d["names"]))


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


def reindex_state(state: PriorState, idx: np.ndarray) -> PriorState:
    """Per-particle state after resampling: rows ``idx`` of every array (``None`` stays ``None``)."""
    if state is None:
        return None
    if isinstance(state, dict):
        return {k: reindex_state(v, idx) for k, v in state.items()}
    return state[idx]


class MotionPrior(ABC):
    """Samples ``p(x_t | x_{t-N} .. x_{t-1})`` for a batch of particles."""

    #: How many past poses the prior conditions on.
    order: int = 1
    #: Name used on the command line and in results.
    name: str = "prior"

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        """Per-particle state from the known initial poses ``n0 x D`` (none by default)."""
        return None

    @abstractmethod
    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        """Next poses ``P x D`` from histories ``P x N x D``.

        ``available`` (1..N) says how many of the most recent history entries
        are real poses; older slots repeat the earliest known pose. A prior
        that needs more history than is available must fall back to a lower
        order (Taylor 2009, Sec. 6.4: "growing" the history).
        """

    def reindex(self, state: PriorState, idx: np.ndarray) -> PriorState:
        return reindex_state(state, idx)

    @abstractmethod
    def diffusion_std(self) -> np.ndarray:
        """Per-dof standard deviation ``(D,)`` (pose units per frame) of the prior's one-step noise: the scale
        annealed filter layers diffuse particles with."""
