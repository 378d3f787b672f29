"""Gaussian Process Dynamical Model (Wang 2005, Ch. 3-5), in torch float64: learning and mean prediction.

Model, for latent coordinates ``X`` (``N x d``, several sequences in one shared
space) and observations ``Y`` (``N x D``, normalised invariant features):

* observation GP (eq. 3.5-3.6): ``k_Y(x, x') = b1 exp(-b2/2 |x - x'|^2) + delta / b3``,
  with a per-dimension scale ``W`` (closed-form update, eq. 4.3);
* dynamics GP (eq. 3.9), first order (input ``x_{t-1}``) or second order
  (input ``[x_{t-1}, x_{t-2}]``, eq. 3.13), with a linear, RBF or linear+RBF
  kernel (eq. 3.10): ``[a1 exp(-sum_k a_{1+k}/2 |x_k - x'_k|^2)] [+ sum_k a_lin,k x_k^T x'_k] + delta / a_noise``.
  Outputs are ``x_t`` for every frame with enough history in its own sequence;
  the first frames of each sequence get an isotropic unit Gaussian prior.

Learning minimises the negative log-posterior (eq. 4.2, with the balanced
prior ``M sum ln b`` of eq. 5.2) over ``X`` and the log hyperparameters by
L-BFGS with autograd; ``W`` is set in closed form every few iterations. Every
log-determinant and solve in the objective goes through a Cholesky factor (no
explicit inverse); a kernel matrix that is not positive definite raises an
:class:`InputError` that says which one and why.

Sparse model, for thousands of frames (``GPDMConfig.inducing``; exact up to
:data:`EXACT_MAX_FRAMES` frames by default): both GPs use inducing points that
are the latent points of ``m`` frames chosen by farthest-point sampling of the
poses (:func:`inducing_frames`), so they move with ``X``; the dynamics GP's
inducing inputs are the dynamics inputs of those frames. Each GP's ``ln p(T)``
is replaced by the DTC (projected process) approximation
``ln N(T; 0, K_fu K_uu^-1 K_uf + s2 I)`` (Seeger et al. 2003; the DTC of
Lawrence 2007's sparse GP-LVM), computed in O(N m^2) by the matrix inversion
lemma. Every frame keeps its latent point, its observation term and its
dynamics term; only the kernel's rank is limited to ``m``.

Prediction (eqs. 4.4-4.5): ``mu_X(x) = X_out^T K_X^-1 k_X(x)``,
``sigma_X^2(x) = k_X(x, x) - k_X(x)^T K_X^-1 k_X(x)``, and the same for the
pose through the observation GP; a sparse model predicts through its inducing
points (the DTC predictive mean and variance). :func:`priors.gpdm.predict.prepare` computes
every factor once; :class:`~priors.gpdm.predict.GPDMSampler` is the tracking prior's batched step.

Training and model files are :mod:`priors.gpdm.training`; the tracking prior (registered as ``gpdm``) is
:mod:`priors.gpdm.prior`.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import ClassVar, Sequence

import numpy as np
import torch

from priors.settings import (  # the settings (priors.settings), read from here too
    AUTO_INDUCING, EXACT_MAX_FRAMES, MIN_INDUCING, SPARSE_METHODS, GPDMConfig,
)
from priors.common import ModelData, normaliser_to_tensors, torch_save_atomic
from priors.gpdm.subset import Stretch
from tracker.core.errors import InputError


FORMAT = "pose-tracker gpdm v1"
#: Training checkpoints have their own format, so a half-trained model is never taken for a model file.
CHECKPOINT_FORMAT = "pose-tracker gpdm training checkpoint v1"
#: Jitter added to the inducing kernel matrix ``K_uu``, relative to its mean diagonal.
JITTER = 1e-6


def n_dynamics_params(cfg: GPDMConfig) -> int:
    """Number of dynamics hyperparameters: RBF scale + one width per lag, one linear scale per lag, noise."""
    n = 1
    if "rbf" in cfg.dynamics:
        n += 1 + cfg.order
    if "linear" in cfg.dynamics:
        n += cfg.order
    return n


def _sqdist(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Squared distances ``n x m`` between the rows of ``a`` and ``b``, as ``|a|^2 + |b|^2 - 2 a b^T`` (one
    matrix product; float64 keeps its rounding near 1e-16 |x|^2)."""
    return ((a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2 * a @ b.T).clamp_min(0)


def _cholesky(K: torch.Tensor, what: str) -> torch.Tensor:
    L, info = torch.linalg.cholesky_ex(K)
    if int(info) != 0:
        raise InputError(f"the {what} kernel matrix is not positive definite (Cholesky failed at row {int(info)}): "
                         "latent points coincide while the noise term is too small; check the data for repeated "
                         "frames or lower the noise precision")
    return L


def dynamics_pairs(lengths: Sequence[int], order: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the dynamics outputs ``(M,)`` and their inputs ``M x order`` (``x_{t-1}``, then ``x_{t-2}``)
    into the concatenated frames of sequences of the given lengths."""
    outs, ins, offset = [], [], 0
    for n in lengths:
        t = np.arange(order, n)
        outs.append(offset + t)
        ins.append(np.stack([offset + t - k for k in range(1, order + 1)], axis=1))
        offset += n
    return np.concatenate(outs), np.concatenate(ins).reshape(-1, order)


def sequence_starts(lengths: Sequence[int], order: int) -> np.ndarray:
    """Indices of each sequence's first ``order`` frames (they have no dynamics input)."""
    offs = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    return np.concatenate([o + np.arange(min(order, n)) for o, n in zip(offs, lengths)])


def pca_init(Y: np.ndarray, d: int) -> np.ndarray:
    """The top ``d`` principal components of centred ``Y`` (``N x d``), scaled to unit variance per axis."""
    Yc = Y - Y.mean(0)
    U, S, _ = np.linalg.svd(Yc, full_matrices=False)
    X = U[:, :d] * S[:d]
    return X / X.std(0).clip(min=1e-12)


def inducing_frames(Y: np.ndarray, m: int) -> np.ndarray:
    """``m`` frames of ``Y`` (``N x D``) by farthest-point sampling, sorted: the frame nearest the mean first,
    then repeatedly the frame farthest (Euclidean, in the normalised features) from all chosen so far.

    Deterministic (ties go to the lowest index). The chosen frames cover the poses evenly, however many frames
    each subject or motion contributes: a rare pose (a start from standing) gets an inducing frame as soon as it
    is farther from the chosen ones than the spacing elsewhere, while hundreds of near-identical frames of a
    long steady walk share a few.
    """
    Y = np.asarray(Y, float)
    N = len(Y)
    if m >= N:
        return np.arange(N)
    chosen = [int(((Y - Y.mean(0)) ** 2).sum(1).argmin())]
    dist = ((Y - Y[chosen[0]]) ** 2).sum(1)
    for _ in range(m - 1):
        i = int(dist.argmax())
        chosen.append(i)
        dist = np.minimum(dist, ((Y - Y[i]) ** 2).sum(1))
    return np.sort(np.array(chosen))


@dataclass
class _Sparse:
    """Factors of a sparse (inducing-point) GP (see :data:`SPARSE_METHODS`) with inducing matrix ``K_uu``,
    cross-covariance ``K_uf`` (``m x n``), prior variances ``k_diag`` (``n``) and noise variance ``s2``:
    ``L L^T = K_uu + jitter``, ``Q = K_fu K_uu^-1 K_uf``, per-point noise ``lam`` (``s2``; FITC:
    ``s2 + diag(K - Q)``), ``A = L^-1 K_uf diag(lam)^-1/2``, ``L_B L_B^T = I + A A^T``. Everything costs
    O(n m^2); with every frame inducing, DTC and VFE equal the exact GP up to the jitter."""

    L: torch.Tensor
    A: torch.Tensor
    LB: torch.Tensor
    lam: torch.Tensor
    trace: torch.Tensor  # tr(K - Q) / s2 (VFE), else 0

    @classmethod
    def of(cls, Kuu: torch.Tensor, Kuf: torch.Tensor, k_diag: torch.Tensor, s2: torch.Tensor, what: str,
           method: str) -> "_Sparse":
        m = Kuu.shape[0]
        eye = torch.eye(m, dtype=Kuu.dtype)
        L = _cholesky(Kuu + JITTER * torch.diagonal(Kuu).mean() * eye, f"{what} inducing")
        A0 = torch.linalg.solve_triangular(L, Kuf, upper=False)
        q = (A0 ** 2).sum(0)
        lam = s2 + (k_diag - q).clamp_min(0) if method == "fitc" else s2.expand(len(q))
        trace = (k_diag - q).sum() / s2 if method == "vfe" else torch.zeros((), dtype=Kuu.dtype)
        A = A0 / lam.sqrt()
        LB = _cholesky(eye + A @ A.T, what)
        return cls(L, A, LB, lam, trace)

    def c(self, T: torch.Tensor) -> torch.Tensor:
        """``L_B^-1 A diag(lam)^-1/2 T`` (``m x k``) for targets ``T`` (``n x k``)."""
        return torch.linalg.solve_triangular(self.LB, self.A @ (T / self.lam.sqrt()[:, None]), upper=False)

    def quad(self, T: torch.Tensor) -> torch.Tensor:
        """``diag(T^T (Q + diag(lam))^-1 T)`` (``k``) by the matrix inversion lemma."""
        return (T ** 2 / self.lam[:, None]).sum(0) - (self.c(T) ** 2).sum(0)

    def nll(self, T: torch.Tensor) -> torch.Tensor:
        """``k/2 ln|Q + diag(lam)| + 1/2 tr(T^T (Q + diag(lam))^-1 T) [+ k/(2 s2) tr(K - Q)]`` for ``k``
        independent outputs, up to a constant: with the trace term the negative of Titsias' (2009)
        variational lower bound on ``ln p(T)``."""
        k = T.shape[1]
        logdet = torch.log(self.lam).sum() + 2 * torch.log(torch.diagonal(self.LB)).sum()
        return 0.5 * k * logdet + 0.5 * self.quad(T).sum() + 0.5 * k * self.trace


_AUTO = object()


class GPDM:
    """A GPDM's parameters (torch float64) and its objective and predictions.

    ``active`` holds the inducing frames (sorted indices into ``Y``) of a sparse model, ``None`` for the exact
    one; by default it follows ``config.inducing`` (:meth:`GPDMConfig.inducing_count`, :func:`inducing_frames`).
    """

    def __init__(self, Y: np.ndarray, lengths: Sequence[int], config: GPDMConfig, X: np.ndarray | None = None,
                 active: np.ndarray | None = _AUTO):
        self.config = cfg = config.check()
        Y = np.asarray(Y, float)
        if Y.ndim != 2 or sum(lengths) != len(Y):
            raise InputError(f"observations must be N x D with N = sum of sequence lengths, got {Y.shape} and "
                             f"{list(lengths)}")
        if min(lengths) <= cfg.order:
            raise InputError(f"every sequence needs more than {cfg.order} frames for order-{cfg.order} dynamics")
        if cfg.latent_dim > Y.shape[1]:
            raise InputError(f"latent dimension must be at most the {Y.shape[1]} observed features, got "
                             f"{cfg.latent_dim}")
        self.Y = torch.tensor(Y, dtype=torch.float64)
        self.lengths = [int(n) for n in lengths]
        out_idx, in_idx = dynamics_pairs(self.lengths, cfg.order)
        self.out_idx, self.in_idx = torch.tensor(out_idx), torch.tensor(in_idx)
        self.start_idx = torch.tensor(sequence_starts(self.lengths, cfg.order))
        if active is _AUTO:
            m = cfg.inducing_count(len(Y))
            active = inducing_frames(Y, m) if m else None
        self.set_active(active)
        d = cfg.latent_dim
        if X is None:
            X = pca_init(Y, d)
        self.X = torch.tensor(X, dtype=torch.float64).requires_grad_(True)
        self.log_alpha = torch.zeros(n_dynamics_params(cfg), dtype=torch.float64, requires_grad=True)
        self.log_beta = torch.zeros(3, dtype=torch.float64, requires_grad=True)
        with torch.no_grad():  # start with moderate noise: precision 100 for Y, 10 for the dynamics
            self.log_beta[2] = math.log(100.0)
            self.log_alpha[-1] = math.log(10.0)
        self.W = torch.ones(Y.shape[1], dtype=torch.float64)
        self.objective_history: list[float] = []
        self.training_seconds = 0.0

    def set_active(self, active: np.ndarray | None) -> None:
        """Make the model sparse with inducing frames ``active`` (indices into ``Y``), or exact (``None``).

        The observation GP's inducing inputs are the latent points of those frames, ``X[active]``; the dynamics
        GP's are the dynamics inputs whose newest lag is one of them. Both move with ``X`` during learning.
        """
        if active is None:
            self.active = self.dyn_active = None
            return
        active = np.unique(np.asarray(active, dtype=np.int64).ravel())
        N = len(self.Y)
        if len(active) < min(MIN_INDUCING, N) or active[0] < 0 or active[-1] >= N:
            where = f" in {active[0]}..{active[-1]}" if len(active) else ""
            raise InputError(f"inducing frames must be at least {min(MIN_INDUCING, N)} distinct indices in "
                             f"0..{N - 1}, got {len(active)}{where}")
        self.active = torch.tensor(active)
        dyn = np.flatnonzero(np.isin(self.in_idx[:, 0].numpy(), active))
        if len(dyn) == 0:
            raise InputError("no inducing frame is the input of a dynamics pair (each is its sequence's last)")
        self.dyn_active = torch.tensor(dyn)

    @property
    def sparse(self) -> bool:
        return self.active is not None

    # --- kernels -----------------------------------------------------------
    def _k_y(self, A: torch.Tensor, B: torch.Tensor) -> torch.Tensor:
        b = self.log_beta.exp()
        return b[0] * torch.exp(-0.5 * b[1] * _sqdist(A, B))

    def _k_x(self, A: torch.Tensor, B: torch.Tensor) -> torch.Tensor:
        """Dynamics kernel between inputs ``n x (order d)`` (lags concatenated), without the noise term.

        ``log_alpha`` holds, in order: for an RBF part its scale and one inverse width per lag; for a linear
        part one scale per lag; last the noise precision.
        """
        a = self.log_alpha.exp()
        o, d = self.config.order, self.config.latent_dim
        K, i = None, 0
        if "rbf" in self.config.dynamics:  # each lag's inverse width scales its coordinates
            s = a[1:1 + o].sqrt().repeat_interleave(d)
            K = a[0] * torch.exp(-0.5 * _sqdist(A * s, B * s))
            i = 1 + o
        if "linear" in self.config.dynamics:
            s = a[i:i + o].sqrt().repeat_interleave(d)
            lin = (A * s) @ (B * s).T
            K = lin if K is None else K + lin
        return K

    def _k_x_diag(self, A: torch.Tensor) -> torch.Tensor:
        """``k_X(x, x)`` ``(n,)`` for inputs ``n x (order d)`` (without noise)."""
        a = self.log_alpha.exp()
        o, d = self.config.order, self.config.latent_dim
        out = torch.zeros(A.shape[0], dtype=A.dtype)
        i = 0
        if "rbf" in self.config.dynamics:
            out = out + a[0]
            i = 1 + o
        if "linear" in self.config.dynamics:
            for k in range(o):
                out = out + a[i + k] * (A[:, k * d:(k + 1) * d] ** 2).sum(-1)
        return out

    def dynamics_inputs(self, X: torch.Tensor | None = None) -> torch.Tensor:
        X = self.X if X is None else X
        return X[self.in_idx].reshape(len(self.in_idx), -1)

    # --- objective ---------------------------------------------------------
    def objective(self) -> torch.Tensor:
        """Negative log-posterior (eq. 4.2 / 5.2), up to a constant."""
        cfg = self.config
        X, Y = self.X, self.Y
        N, D = Y.shape
        d = cfg.latent_dim
        a = self.log_alpha.exp()
        b = self.log_beta.exp()
        Xin = self.dynamics_inputs()
        Xout = X[self.out_idx]
        start = 0.5 * (X[self.start_idx] ** 2).sum()
        if self.sparse:
            Zin = Xin[self.dyn_active]
            dyn = _Sparse.of(self._k_x(Zin, Zin), self._k_x(Zin, Xin), self._k_x_diag(Xin), 1 / a[-1],
                             "dynamics", cfg.sparse_method).nll(Xout) + self.log_alpha.sum()
            Xu = X[self.active]
            sy = _Sparse.of(self._k_y(Xu, Xu), self._k_y(Xu, X), b[0].expand(N), 1 / b[2], "observation",
                            cfg.sparse_method)
            rec = (-N * torch.log(self.W).sum() + sy.nll(Y * self.W)
                   + cfg.balance * self.log_beta.sum())
            return dyn + rec + start
        KX = self._k_x(Xin, Xin) + torch.eye(len(Xin), dtype=X.dtype) / a[-1]
        LX = _cholesky(KX, "dynamics")
        KY = self._k_y(X, X) + torch.eye(N, dtype=X.dtype) / b[2]
        LY = _cholesky(KY, "observation")
        half_logdet = lambda L: torch.log(torch.diagonal(L)).sum()  # noqa: E731  (= 1/2 ln|K|)
        sx = torch.linalg.solve_triangular(LX, Xout, upper=False)
        sy = torch.linalg.solve_triangular(LY, Y * self.W, upper=False)
        dyn = d * half_logdet(LX) + 0.5 * (sx ** 2).sum() + self.log_alpha.sum()
        rec = (-N * torch.log(self.W).sum() + D * half_logdet(LY) + 0.5 * (sy ** 2).sum()
               + cfg.balance * self.log_beta.sum())
        return dyn + rec + start

    def update_W(self) -> None:
        """Closed-form scales (eq. 4.3): ``w_k = sqrt(N / (y_k^T K_Y^-1 y_k))``."""
        with torch.no_grad():
            N = self.Y.shape[0]
            if self.sparse:  # the same with (Q + Lam)^-1 (VFE's trace term does not depend on W)
                Xu = self.X[self.active]
                b = self.log_beta.exp()
                sp = _Sparse.of(self._k_y(Xu, Xu), self._k_y(Xu, self.X), b[0].expand(N), 1 / b[2], "observation",
                                self.config.sparse_method)
                self.W = torch.sqrt(N / sp.quad(self.Y).clamp_min(1e-12))
                return
            KY = self._k_y(self.X, self.X) + torch.eye(N, dtype=torch.float64) / self.log_beta.exp()[2]
            LY = _cholesky(KY, "observation")
            s = torch.linalg.solve_triangular(LY, self.Y, upper=False)
            self.W = torch.sqrt(N / (s ** 2).sum(0).clamp_min(1e-12))

    def parameters(self) -> list[torch.Tensor]:
        return [self.X, self.log_alpha, self.log_beta]


# ---------------------------------------------------------------------------
# Model files (read back by :mod:`priors.gpdm.file`)
# ---------------------------------------------------------------------------

def gpdm_document(model: GPDM, extra: dict | None = None) -> dict:
    """The model file's dictionary (tensors and plain values; ``torch.load(weights_only=True)`` reads it)."""
    return {"format": FORMAT, "config": asdict(model.config), "lengths": list(model.lengths),
            "X": model.X.detach().clone(), "Y": model.Y.clone(), "W": model.W.clone(),
            "log_alpha": model.log_alpha.detach().clone(), "log_beta": model.log_beta.detach().clone(),
            "active": None if model.active is None else model.active.clone(),
            "objective_history": [float(v) for v in model.objective_history], "extra": extra or {}}


def save_gpdm(path: str | Path, model: GPDM, extra: dict | None = None, overwrite: bool = True) -> None:
    """Write a trained GPDM (latent points, data, scales, hyperparameters, config) and ``extra`` metadata
    (plain values or tensors) to a ``torch.save`` file loadable with ``weights_only=True``, atomically
    (:func:`priors.common.torch_save_atomic`; an existing file is refused unless ``overwrite``)."""
    torch_save_atomic(gpdm_document(model, extra), Path(path), overwrite)


@dataclass(kw_only=True)
class GPDMPriorModel(ModelData):
    """A GPDM trained on pose clips, with the normaliser and data settings it was trained with
    (:class:`~priors.common.ModelData`)."""

    gpdm: GPDM
    #: The stretches of the training clips it was trained on, when the corpus was cut (:mod:`priors.gpdm.subset`);
    #: None: every frame of :attr:`sources`.
    subset: list[Stretch] | None = None
    #: Frames of the whole corpus the subset was cut from (0 when not known or not cut).
    corpus_frames: int = 0

    KIND: ClassVar[str] = "GPDM"

    def save(self, path: str | Path, overwrite: bool = False) -> None:
        """The model file at ``path`` (atomically); an existing one is refused unless ``overwrite``."""
        save_gpdm(path, self.gpdm, overwrite=overwrite, extra={
            "fps": float(self.fps), "body_model": self.body_model, "dof_names": list(self.dof_names),
            "sources": list(self.sources), "pose_step_rms": torch.tensor(self.pose_step_rms),
            "normaliser": normaliser_to_tensors(self.normaliser),
            "training_seconds": float(self.gpdm.training_seconds),
            **({} if self.subset is None else {"subset": [s.as_dict() for s in self.subset],
                                               "corpus_frames": int(self.corpus_frames)})})

    def summary(self) -> str:
        """One line on how training went."""
        h, c = self.gpdm.objective_history, self.gpdm.config
        fit = f"objective {h[0]:.1f} -> {h[-1]:.1f}, " if h else ""
        g = self.gpdm
        size = (f"{len(g.Y)} frames, {len(g.active)} inducing" if g.sparse else f"{len(g.Y)} frames, exact")
        cut = "" if self.subset is None else (
            f" (a subset: {len(self.subset)} stretch(es) of {len(set(s.source for s in self.subset))} clip(s) of "
            f"the {self.corpus_frames} frames given, listed in the model file)")
        return (f"{c.latent_dim}D GPDM ({c.dynamics} dynamics, order {c.order}; {size}{cut}): {fit}"
                f"{g.training_seconds:.1f} s")
