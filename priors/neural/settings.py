"""The neural prior's training settings and the options that set them, without torch (the command line lists
them from here; the model loads only when the prior is built or trained)."""
from __future__ import annotations

from dataclasses import dataclass
from numbers import Integral
from typing import ClassVar

from priors.settings import PACE_SPREAD_FOR_INPUT
from tracker.core.errors import InputError
from tracker.engine.registry import Option


@dataclass
class NeuralConfig:
    """Training settings of the neural prior: a mixture density network of ``components`` diagonal Gaussians
    over the next frame's normalised features, given an MLP (``layers`` hidden layers of ``hidden`` units)
    encoding of up to ``order`` history frames; trained by Adam on mini-batches of ``batch_size`` windows, each
    window's history cut to a random length of 1 .. ``order`` frames, so one model draws from any history."""

    order: int = 4
    hidden: int = 128
    layers: int = 2
    components: int = 8
    epochs: int = 100
    batch_size: int = 256
    learning_rate: float = 1e-3
    #: Std of the Gaussian noise on the history in training (normalised units), or "auto": per feature a
    #: quarter of the 99th percentile of its frame-to-frame change (the CRBM's auto noise, scaled down: the
    #: network widens its predicted spread where the history is noisy).
    history_noise: float | str = "auto"
    #: Condition on each frame's pace (as the CRBM does: :class:`priors.parts.PaceInput`).
    pace_input: bool = False
    #: Fraction of each clip (its last frames) held out: the weights of the epoch with the least held-out
    #: negative log-likelihood are kept (0: the last epoch's).
    validation: float = 0.1

    KIND: ClassVar[str] = "neural prior"
    COUNTS: ClassVar[tuple[str, ...]] = ("order", "hidden", "layers", "components", "epochs", "batch_size")

    def check(self) -> "NeuralConfig":
        """The config itself, checked; a bad setting is an :class:`InputError` naming it."""
        for name in self.COUNTS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, Integral) or value < 1:
                raise InputError(f"{self.KIND} {name} must be an integer of at least 1, got {value!r}")
        rate = self.learning_rate
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate < 1:
            raise InputError(f"{self.KIND} learning_rate must lie in (0, 1), got {rate!r}")
        noise = self.history_noise
        if noise != "auto" and (isinstance(noise, bool) or not isinstance(noise, (int, float))
                                or not 0 <= noise <= 100):
            raise InputError(f"history noise must be 'auto' or a number in [0, 100], got {noise!r}")
        if isinstance(self.validation, bool) or not isinstance(self.validation, (int, float)) \
                or not 0 <= self.validation <= 0.5:
            raise InputError(f"{self.KIND} validation must lie in [0, 0.5], got {self.validation!r}")
        if not isinstance(self.pace_input, bool):
            raise InputError(f"{self.KIND} pace_input must be true or false, got {self.pace_input!r}")
        return self


NEURAL_TRAIN_OPTIONS = (
    Option("order", int, NeuralConfig.order, "most history frames the network reads (it draws from any number "
                                            "from 1 up)", minimum=1, maximum=100, unit="frames"),
    Option("hidden", int, NeuralConfig.hidden, "units of each hidden layer", minimum=1, maximum=100000),
    Option("layers", int, NeuralConfig.layers, "hidden layers of the history encoder", minimum=1, maximum=20),
    Option("components", int, NeuralConfig.components, "Gaussian components of the mixture over the next frame",
           minimum=1, maximum=1000),
    Option("epochs", int, NeuralConfig.epochs, "passes through the data", minimum=1, maximum=1000000),
    Option("batch_size", int, NeuralConfig.batch_size, "windows per mini-batch", minimum=1, maximum=1000000),
    Option("learning_rate", float, NeuralConfig.learning_rate, "Adam's step size", minimum=0.0, strict=True,
           maximum=1.0, strict_max=True),
    Option("history_noise", str, "auto",
           "std of the noise added to the history in training (normalised units), or 'auto': per feature a quarter "
           "of the 99th percentile of its frame-to-frame change"),
    Option("pace_input", bool, None, "condition the model on each frame's pace (log ground speed averaged over one "
                                     "second), which each particle carries while tracking",
           default_note=f"on when the clips' paces vary, std of log pace >= {PACE_SPREAD_FOR_INPUT:g}; "
                        "--no-pace-input to turn it off"),
    Option("validation", float, NeuralConfig.validation,
           "fraction of each clip (its last frames) held out: the weights of the epoch with the least held-out "
           "negative log-likelihood are kept", minimum=0.0, maximum=0.5, default_note="0.1; 0: the last epoch's"),
    Option("checkpoint_every", int, None, "also save the training state every this many epochs, for train --resume",
           minimum=1, default_note="never"),
)
