"""Factored, style-gated Conditional RBM motion prior (Taylor & Hinton, ICML 2009; Taylor 2009, Ch. 5), in torch.

Model (Gaussian visible units with unit variance on normalised invariant features ``v_t`` ``(K,)``, binary hidden
units ``h_t`` ``(H,)``, history ``v_<t`` ``(N K,)`` oldest first, one-hot or blended labels ``y_t`` ``(P,)``)::

    z_t  = R^T y_t                                            style features (L,)        (eq. 6)
    s_f  = sum_l Z_lf z_l                                      style input to factor f    (tied, Sec. 3.1)
    a_hat = a + Av [(Ap^T v_<t) * s]                           dynamic visible bias       (eq. 4)
    b_hat = b + Bh [(Bp^T v_<t) * s]                           dynamic hidden bias        (eq. 5)
    E = 1/2 |v_t - a_hat|^2 - sum_f (Wv^T v_t)_f (Wh^T h_t)_f s_f - b_hat . h_t              (eq. 3)
    p(h_j = 1 | v_t, v_<t, y_t) = sigmoid(b_hat_j + sum_f Wh_jf (Wv^T v_t)_f s_f)            (eq. 5.12)
    p(v_t | h_t, v_<t, y_t)     = N(a_hat + Wv [(Wh^T h_t) * s], I)                          (eq. 5.13)
    F(v_t | v_<t, y_t) = 1/2 |v_t - a_hat|^2 - sum_j softplus(b_hat_j + sum_f Wh_jf (Wv^T v_t)_f s_f)

Shapes of the parameters: ``Wv`` ``K x F``, ``Wh`` ``H x F``, ``Av`` ``K x F``, ``Ap`` ``NK x F``, ``Bh`` ``H x F``,
``Bp`` ``NK x F``, ``Z`` ``L x F`` (the feature-to-factor weights, tied between the three sub-models as in the
paper's reported models: ``W^z = A^z = B^z``, so all three sub-models have ``F`` factors), ``R`` ``P x L``, biases
``a`` ``(K,)`` and ``b`` ``(H,)``.

Training: CD-k on mini-batches of randomly permuted (N+1)-frame windows (every window carries its clip's label),
the statistics of eqs. 5.14-5.23 (:meth:`FCRBM.free_energy_gradients`: the gradient of the free energy, hidden
probabilities in both phases; binary hidden samples drive the reconstructions), momentum 0.9, weight decay on the
weights, learning rate 1e-2 except the autoregressive parameters ``Av``, ``Ap``, the autoregressive part of the
tied ``Z`` and the label-to-feature ``R``, which learn at 1e-3 (Sec. 4.2). Gaussian noise on the history as for the
CRBM (:func:`priors.crbm.training.history_noise_scale`), and the labels are balanced by repeating the windows of the rarer
ones (the paper repeats its shorter sequences).

Generation: alternating Gibbs sampling from the last history frame with the labels clamped (binary hidden samples,
expected visible values, probabilities on the final step). Blends and transitions interpolate the label vector
(:func:`priors.fcrbm.prior.generate`, :func:`priors.fcrbm.prior.transition_styles`).

Tracking (:class:`priors.fcrbm.prior.FCRBMPrior`, registered as ``fcrbm``): each particle carries a discrete style label besides its
pose history, and its pose is drawn with its label clamped. An equal share of the particles carries
each label and the filter weighs the labels against each other (mixture tracking, :mod:`tracker.engine.multiple_models`,
switching with probability ``style_switch`` per frame). The filter's posterior over the style is the weighted histogram of the
particles' labels (:meth:`priors.fcrbm.prior.FCRBMPrior.summarize`), recorded per frame in ``result.json``. Particles
that share a label share the effective weights ``Wv diag(s) Wh^T``, so sampling works on one ``K x H`` matrix per
label (:meth:`FCRBM.gibbs`).
"""
from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import ClassVar, Sequence

import torch

from priors.common import TrainedModel
from priors.crbm.model import below_, uniform16
from priors.settings import FCRBMConfig
from tracker.core.errors import InputError

FORMAT = "pose-tracker fcrbm v1"
#: The format of a training checkpoint (``train --checkpoint-every``), never taken for a model file.
CHECKPOINT_FORMAT = "pose-tracker fcrbm training checkpoint v1"

#: A label: letters, digits, '_', '-' and '.', starting with a letter or digit.
LABEL_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$")
#: With at most this many distinct style rows in a batch, Gibbs sampling uses one effective weight matrix per row
#: value (:meth:`FCRBM.gibbs`); with more (e.g. every particle a different blend) the factored form.
GROUPED_STYLES_MAX = 16
#: How the FCRBM prior infers an unknown style: ``"mixture"`` keeps a fixed share of the particles on every label
#: and moves weight between them (mixture tracking, :mod:`tracker.engine.multiple_models`); ``"particles"`` lets every
#: particle carry and switch its own label, the posterior being the weighted histogram.




def parse_labels(text: str | Sequence[str], sources: Sequence[str]) -> list[str]:
    """One label per training clip, in clip order, from ``"walk,walk,run"`` (a list, or the text of one, is
    accepted too). A wrong count or a malformed label is an :class:`InputError` naming the clips."""
    items = list(text) if isinstance(text, (list, tuple)) else str(text).split(",")
    labels = [str(t).strip().strip("[]'\" ") for t in items]
    labels = [t for t in labels if t] if len(labels) > 1 or labels[0] else []
    where = ", ".join(Path(s).name for s in sources) or None
    if len(labels) != len(sources):
        raise InputError(f"labels: {len(labels)} label(s) given for {len(sources)} training clip(s); give one per "
                         "clip in clip order, e.g. --labels walk,walk,run", where)
    bad = [t for t in labels if not LABEL_PATTERN.match(t)]
    if bad:
        raise InputError(f"labels: {bad[0]!r} is not a label (letters, digits, '_', '-', '.')",
                         sources[labels.index(bad[0])])
    return labels


def one_hot(index: torch.Tensor, n: int, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """Rows ``B x n`` with a one at ``index`` ``(B,)``."""
    out = torch.zeros(len(index), n, dtype=dtype, device=index.device)
    out[torch.arange(len(index), device=index.device), index] = 1
    return out


class FCRBM:
    """Parameters and inference of one factored, style-gated CRBM (tensors of one dtype on one device)."""

    PARAMS = ("Wv", "Wh", "Av", "Ap", "Bh", "Bp", "Z", "R", "a", "b")
    #: Parameters with weight decay (every weight matrix; not the biases).
    DECAYED = ("Wv", "Wh", "Av", "Ap", "Bh", "Bp", "Z", "R")
    #: Parameters that learn at the smaller autoregressive rate (with the autoregressive part of ``Z``).
    SLOW = ("Av", "Ap", "R")

    def __init__(self, n_visible: int, n_hidden: int, order: int, n_labels: int, n_features: int, n_factors: int,
                 generator: torch.Generator | None = None, device: str | torch.device = "cpu",
                 dtype: torch.dtype = torch.float32):
        K, H, N, P, L, F = n_visible, n_hidden, order, n_labels, n_features, n_factors
        self.n_visible, self.n_hidden, self.order, self.n_labels = K, H, N, P
        self.n_features, self.n_factors = L, F
        kw = {"device": torch.device(device), "dtype": dtype, "generator": generator}
        shapes = self.shapes()
        # Unit-to-factor weights small (as the CRBM's), style path of unit scale so that the three-way products
        # are not all vanishingly small at the start: z ~ N(0, 1), s = Z^T z ~ N(0, 1).
        scale = {"R": 1.0, "Z": 1.0 / math.sqrt(L)}
        self.params = {k: (torch.randn(*shapes[k], **kw) * scale.get(k, 0.05)) if k not in ("a", "b") else
                       torch.zeros(*shapes[k], device=kw["device"], dtype=dtype) for k in self.PARAMS}

    def shapes(self) -> dict[str, tuple[int, ...]]:
        K, H, N, P, L, F = (self.n_visible, self.n_hidden, self.order, self.n_labels, self.n_features,
                            self.n_factors)
        return {"Wv": (K, F), "Wh": (H, F), "Av": (K, F), "Ap": (N * K, F), "Bh": (H, F), "Bp": (N * K, F),
                "Z": (L, F), "R": (P, L), "a": (K,), "b": (H,)}

    def __getattr__(self, name: str) -> torch.Tensor:
        params = self.__dict__.get("params")
        if params is not None and name in params:
            return params[name]
        raise AttributeError(name)

    def to(self, device: str | torch.device | None = None, dtype: torch.dtype | None = None) -> "FCRBM":
        """Move (or convert) every parameter, in place; returns self."""
        self.params = {k: v.to(device or v.device, dtype or v.dtype) for k, v in self.params.items()}
        return self

    def state_dict(self) -> dict[str, torch.Tensor]:
        return {k: v.detach().cpu().clone() for k, v in self.params.items()}

    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        ref = self.params["a"]
        self.params = {k: state[k].to(ref.device, ref.dtype) for k in self.PARAMS}

    # -- inference ------------------------------------------------------------------------------------------

    def style_factors(self, y: torch.Tensor) -> torch.Tensor:
        """The style's input ``B x F`` to every factor from label rows ``y`` ``B x P`` (one-hot or blends)."""
        return (y @ self.R) @ self.Z

    def biases(self, history: torch.Tensor, s: torch.Tensor,
               projected: tuple[torch.Tensor, torch.Tensor] | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Dynamic biases ``a_hat`` ``B x K`` and ``b_hat`` ``B x H`` from histories ``B x NK`` and style factors
        (``projected``: the histories' ``history @ Ap`` and ``history @ Bp`` where already computed)."""
        ap, bp = projected if projected is not None else (history @ self.Ap, history @ self.Bp)
        return self.a + (ap * s) @ self.Av.T, self.b + (bp * s) @ self.Bh.T

    def conditioning(self, history: torch.Tensor, y: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """What a training step computes once from histories ``B x NK`` and labels ``B x P`` for both phases: the
        style features ``y R`` ``B x L``, the style factors ``B x F`` and the projected histories ``history @ Ap``
        and ``history @ Bp`` ``B x F`` (the same numbers :meth:`style_factors` and :meth:`biases` compute)."""
        zs = y @ self.R
        return zs, zs @ self.Z, history @ self.Ap, history @ self.Bp

    def hidden_probabilities(self, v: torch.Tensor, s: torch.Tensor, b_hat: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(b_hat + ((v @ self.Wv) * s) @ self.Wh.T)

    def visible_means(self, h: torch.Tensor, s: torch.Tensor, a_hat: torch.Tensor) -> torch.Tensor:
        return a_hat + ((h @ self.Wh) * s) @ self.Wv.T

    def free_energy(self, v: torch.Tensor, history: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """Free energy ``(B,)`` of frames ``v`` ``B x K`` given histories ``B x NK`` and labels ``B x P``."""
        s = self.style_factors(y)
        a_hat, b_hat = self.biases(history, s)
        x = b_hat + ((v @ self.Wv) * s) @ self.Wh.T
        return 0.5 * ((v - a_hat) ** 2).sum(-1) - torch.nn.functional.softplus(x).sum(-1)

    def free_energy_gradients(self, v: torch.Tensor, history: torch.Tensor, y: torch.Tensor,
                              conditioning: tuple[torch.Tensor, ...] | None = None) -> dict[str, torch.Tensor]:
        """The batch mean of ``dF/dtheta`` for every parameter (eqs. 5.14-5.23 up to sign: the CD statistic of a
        phase), plus ``'Z_autoregressive'``, the part of ``dF/dZ`` that reaches the tied ``Z`` through the
        autoregressive sub-model (it learns at the autoregressive rate). ``conditioning``: :meth:`conditioning`
        of ``history`` and ``y``, where already computed."""
        n = len(v)
        zs, s, ap, bp = conditioning if conditioning is not None else self.conditioning(history, y)
        fv = v @ self.Wv
        am, bm = ap * s, bp * s
        e = v - (self.a + am @ self.Av.T)                       # -dF/da_hat
        p = torch.sigmoid(self.b + bm @ self.Bh.T + (fv * s) @ self.Wh.T)  # -dF/db_hat
        g, q, r = p @ self.Wh, p @ self.Bh, e @ self.Av           # -dF/d(factor products)
        ds_rest, ds_ar = -(g * fv) - (q * bp), -(r * ap)          # dF/ds through W and B, through A
        ds = ds_rest + ds_ar
        return {
            "Wv": -(v.T @ (g * s)) / n, "Wh": -(p.T @ (fv * s)) / n,
            "Av": -(e.T @ am) / n, "Ap": -(history.T @ (r * s)) / n,
            "Bh": -(p.T @ bm) / n, "Bp": -(history.T @ (q * s)) / n,
            "Z": zs.T @ ds / n, "Z_autoregressive": zs.T @ ds_ar / n,
            "R": y.T @ (ds @ self.Z.T) / n, "a": -e.mean(0), "b": -p.mean(0),
        }

    def gibbs(self, history: torch.Tensor, y: torch.Tensor, steps: int, generator: torch.Generator | None,
              init: torch.Tensor | None = None, grouped: bool | None = None) -> torch.Tensor:
        """Next frames ``B x K`` by alternating Gibbs sampling with the labels ``y`` ``B x P`` clamped, from ``init``
        (default: the last history frame): binary hidden samples, expected visible values, hidden probabilities
        on the final step (as :meth:`priors.crbm.model.CRBM.gibbs`).

        Rows with the same label vector share the effective weights ``Wv diag(s) Wh^T`` ``K x H``; with at most
        :data:`GROUPED_STYLES_MAX` distinct rows (``grouped=None``) sampling runs on those matrices, rows sorted
        by style, else on the factored form. Both draw the same random numbers (one ``B x H`` array of uniform
        integers per step, :func:`priors.crbm.model.uniform16`, its rows taken in the order of the rows sorted by style)
        and agree to rounding. Sampling writes into its arrays in place (``out=``), so parameters must not require
        gradients (training uses the explicit CD statistics of :meth:`free_energy_gradients`).
        """
        s = self.style_factors(y)
        a_hat, b_hat = self.biases(history, s)
        v = history[:, -self.n_visible:] if init is None else init
        B, H = len(v), self.n_hidden
        styles, inverse, order = group_rows(y)
        if grouped is None:
            grouped = len(styles) <= GROUPED_STYLES_MAX
        if not grouped:
            rank = torch.empty_like(order)
            rank[order] = torch.arange(B, device=order.device)
            for step in range(steps):
                p = self.hidden_probabilities(v, s, b_hat)
                h = p if step == steps - 1 else below_(uniform16((B, H), generator, v.device)[rank], p)
                v = self.visible_means(h, s, a_hat)
            return v
        weights = torch.einsum("kf,sf,hf->skh", self.Wv, self.style_factors(styles), self.Wh)  # S x K x H
        bounds = [0] + torch.cumsum(torch.bincount(inverse, minlength=len(styles)), 0).tolist()
        groups = [(slice(bounds[i], bounds[i + 1]), weights[i]) for i in range(len(styles))]
        a_hat, b_hat, v = a_hat[order], b_hat[order], v[order]
        h = torch.empty((B, H), device=v.device, dtype=v.dtype)
        for step in range(steps):
            u = None if step == steps - 1 else uniform16((B, H), generator, v.device)
            for rows, W in groups:  # h[rows], v[rows]: views of contiguous row blocks, written in place
                torch.addmm(b_hat[rows], v[rows], W, out=h[rows]).sigmoid_()
                if u is not None:
                    below_(u[rows], h[rows])
            v = torch.empty_like(v)
            for rows, W in groups:
                torch.addmm(a_hat[rows], h[rows], W.T, out=v[rows])
        out = torch.empty_like(v)
        out[order] = v
        return out


def group_rows(y: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The distinct rows of ``y`` ``B x P`` in lexicographic order ``S x P`` (as ``torch.unique(y, dim=0)``), each
    row's index among them ``(B,)``, and the stable permutation ``(B,)`` that sorts the rows by it.

    Successive stable sorts of the columns, last column first: a few 1-D sorts instead of ``torch.unique``'s
    row-by-row comparisons (about ten times faster for 1000 rows on CPU).
    """
    order = torch.arange(len(y), device=y.device)
    for column in reversed(range(y.shape[1])):
        order = order[torch.argsort(y[order, column], stable=True)]
    ordered = y[order]
    first = torch.ones(len(y), dtype=torch.bool, device=y.device)
    first[1:] = (ordered[1:] != ordered[:-1]).any(1)
    inverse = torch.empty_like(order)
    inverse[order] = torch.cumsum(first, 0) - 1
    return ordered[first], inverse, order


# ---------------------------------------------------------------------------
# The trained model: FCRBM + labels + normaliser + the settings it was trained with
# ---------------------------------------------------------------------------

@dataclass(kw_only=True)
class FCRBMModel(TrainedModel):
    """A trained FCRBM: its weights, settings and labels (with each training clip's), the lower orders it grows
    from, and what :class:`~priors.common.TrainedModel` keeps."""

    fcrbm: FCRBM
    labels: list[str]
    config: FCRBMConfig
    clip_labels: list[str]
    #: Lower-order FCRBMs trained with this one on the same clips and labels, which grow the history from the
    #: known frames (as the CRBM's, Taylor 2009 Sec. 6.4); saved in the same file.
    growth: list["FCRBMModel"] = field(default_factory=list)

    KIND: ClassVar[str] = "FCRBM"

    @property
    def order(self) -> int:
        return self.fcrbm.order

    def summary(self) -> str:
        """One line on how training went."""
        fit = self.fit_note()
        grow = f" (grows from order {', '.join(str(g.order) for g in self.growth)})" if self.growth else ""
        return (f"FCRBM order {self.order}{grow}, {self.fcrbm.n_hidden} hidden units, {self.fcrbm.n_factors} "
                f"factors, labels {', '.join(self.labels)}: {fit}"
                f"{self.training_seconds:.1f} s")

    def to_document(self) -> dict:
        """The model file's dictionary (tensors and plain values; ``torch.load(weights_only=True)`` reads it)."""
        return {"format": FORMAT, "params": self.fcrbm.state_dict(), "labels": list(self.labels),
                "config": asdict(self.config), **self.data_document(), "clip_labels": list(self.clip_labels),
                "growth": [g.to_document() for g in self.growth]}

    def label_index(self, label: str) -> int:
        if label not in self.labels:
            raise InputError(f"style {label!r} is not a label of this FCRBM (its labels: {', '.join(self.labels)})")
        return self.labels.index(label)
