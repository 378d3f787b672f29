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
log-determinant and solve goes through a Cholesky factor (no explicit
inverse); a kernel matrix that is not positive definite raises an
:class:`InputError` that says which one and why.

Prediction (eqs. 4.4-4.5): ``mu_X(x) = X_out^T K_X^-1 k_X(x)``,
``sigma_X^2(x) = k_X(x, x) - k_X(x)^T K_X^-1 k_X(x)``, and the same for the
pose through the observation GP.

Registered as the ``gpdm`` prior (``train`` and ``track --prior gpdm``).
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from priors.common import (
    ROOT_NOISE_MM, add_ground_diffusion, check_model_fits, normaliser_from_tensors, normaliser_to_tensors,
    read_model_file, torch_generator,
)
from tracker.core.errors import InputError
from tracker.core.representation import (
    STEP_FEATURES, FeatureNormaliser, clip_features, next_poses, pending_step, poses_to_invariant, step_rms,
)
from tracker.engine.prior import MotionPrior, PriorState
from tracker.engine.registry import Option, PriorContext, TrainingData, register_prior

FORMAT = "pose-tracker gpdm v1"
DYNAMICS = ("linear", "rbf", "linear+rbf")


@dataclass
class GPDMConfig:
    latent_dim: int = 3
    dynamics: str = "linear+rbf"
    order: int = 1
    balance: float = 1.0
    iterations: int = 300
    w_update_every: int = 10

    def check(self) -> "GPDMConfig":
        if self.latent_dim < 1:
            raise InputError(f"latent dimension must be at least 1, got {self.latent_dim}")
        if self.dynamics not in DYNAMICS:
            raise InputError(f"dynamics kernel must be one of {', '.join(DYNAMICS)}, got {self.dynamics!r}")
        if self.order not in (1, 2):
            raise InputError(f"GPDM order must be 1 or 2, got {self.order}")
        if not self.balance > 0:
            raise InputError(f"the balance M must be positive, got {self.balance}")
        if self.iterations < 1 or self.w_update_every < 1:
            raise InputError("iterations and the W update interval must be at least 1")
        return self


def n_dynamics_params(cfg: GPDMConfig) -> int:
    """Number of dynamics hyperparameters: RBF scale + one width per lag, one linear scale per lag, noise."""
    n = 1
    if "rbf" in cfg.dynamics:
        n += 1 + cfg.order
    if "linear" in cfg.dynamics:
        n += cfg.order
    return n


def _sqdist(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return ((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)


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


class GPDM:
    """A GPDM's parameters (torch float64) and its objective and predictions."""

    def __init__(self, Y: np.ndarray, lengths: Sequence[int], config: GPDMConfig, X: np.ndarray | None = None):
        self.config = cfg = config.check()
        Y = np.asarray(Y, float)
        if Y.ndim != 2 or sum(lengths) != len(Y):
            raise InputError(f"observations must be N x D with N = sum of sequence lengths, got {Y.shape} and "
                             f"{list(lengths)}")
        if min(lengths) <= cfg.order:
            raise InputError(f"every sequence needs more than {cfg.order} frames for order-{cfg.order} dynamics")
        self.Y = torch.tensor(Y, dtype=torch.float64)
        self.lengths = [int(n) for n in lengths]
        out_idx, in_idx = dynamics_pairs(self.lengths, cfg.order)
        self.out_idx, self.in_idx = torch.tensor(out_idx), torch.tensor(in_idx)
        self.start_idx = torch.tensor(sequence_starts(self.lengths, cfg.order))
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
        K = torch.zeros(A.shape[0], B.shape[0], dtype=A.dtype)
        i = 0
        if "rbf" in self.config.dynamics:
            expo = torch.zeros_like(K)
            for k in range(o):
                expo = expo + a[1 + k] * _sqdist(A[:, k * d:(k + 1) * d], B[:, k * d:(k + 1) * d])
            K = K + a[0] * torch.exp(-0.5 * expo)
            i = 1 + o
        if "linear" in self.config.dynamics:
            for k in range(o):
                K = K + a[i + k] * (A[:, k * d:(k + 1) * d] @ B[:, k * d:(k + 1) * d].T)
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
        start = 0.5 * (X[self.start_idx] ** 2).sum()
        return dyn + rec + start

    def update_W(self) -> None:
        """Closed-form scales (eq. 4.3): ``w_k = sqrt(N / (y_k^T K_Y^-1 y_k))``."""
        with torch.no_grad():
            N = self.Y.shape[0]
            KY = self._k_y(self.X, self.X) + torch.eye(N, dtype=torch.float64) / self.log_beta.exp()[2]
            LY = _cholesky(KY, "observation")
            s = torch.linalg.solve_triangular(LY, self.Y, upper=False)
            self.W = torch.sqrt(N / (s ** 2).sum(0).clamp_min(1e-12))

    def parameters(self) -> list[torch.Tensor]:
        return [self.X, self.log_alpha, self.log_beta]

    # --- prediction --------------------------------------------------------
    def prepare(self) -> "GPDMPredictor":
        return GPDMPredictor.of(self)


@dataclass
class GPDMPredictor:
    """Everything mean prediction needs, as plain tensors (no autograd)."""

    config: GPDMConfig
    X: torch.Tensor
    Y: torch.Tensor
    W: torch.Tensor
    log_alpha: torch.Tensor
    log_beta: torch.Tensor
    in_idx: torch.Tensor
    out_idx: torch.Tensor
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, m: GPDM) -> "GPDMPredictor":
        return cls(m.config, m.X.detach().clone(), m.Y.clone(), m.W.clone(), m.log_alpha.detach().clone(),
                   m.log_beta.detach().clone(), m.in_idx.clone(), m.out_idx.clone())

    def _model(self) -> GPDM:
        g = GPDM.__new__(GPDM)
        g.config, g.X, g.Y, g.W = self.config, self.X, self.Y, self.W
        g.log_alpha, g.log_beta, g.in_idx, g.out_idx = self.log_alpha, self.log_beta, self.in_idx, self.out_idx
        return g

    def _factors(self) -> dict:
        if not self._cache:
            g = self._model()
            a, b = self.log_alpha.exp(), self.log_beta.exp()
            Xin = g.dynamics_inputs()
            KX = g._k_x(Xin, Xin) + torch.eye(len(Xin), dtype=torch.float64) / a[-1]
            LX = _cholesky(KX, "dynamics")
            KY = g._k_y(self.X, self.X) + torch.eye(len(self.X), dtype=torch.float64) / b[2]
            LY = _cholesky(KY, "observation")
            self._cache.update(g=g, Xin=Xin, LX=LX, LY=LY,
                               alpha_X=torch.cholesky_solve(self.X[self.out_idx], LX),
                               alpha_Y=torch.cholesky_solve(self.Y, LY))
        return self._cache

    def predict_latent(self, inputs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean ``B x d`` and variance ``(B,)`` of the next latent point for dynamics inputs ``B x (order d)``."""
        f = self._factors()
        k = f["g"]._k_x(inputs, f["Xin"])  # B x M
        mean = k @ f["alpha_X"]
        v = torch.linalg.solve_triangular(f["LX"], k.T, upper=False)
        var = f["g"]._k_x_diag(inputs) + 1.0 / self.log_alpha.exp()[-1] - (v ** 2).sum(0)
        return mean, var.clamp_min(1e-12)

    def predict_pose(self, latent: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean ``B x D`` (normalised features) and per-dimension variance ``B x D`` of poses at latent points."""
        f = self._factors()
        k = f["g"]._k_y(latent, self.X)
        mean = k @ f["alpha_Y"]
        v = torch.linalg.solve_triangular(f["LY"], k.T, upper=False)
        b = self.log_beta.exp()
        var = (b[0] + 1.0 / b[2] - (v ** 2).sum(0)).clamp_min(1e-12)
        return mean, var[:, None] / self.W[None, :] ** 2

    def project(self, poses: torch.Tensor, iterations: int = 50) -> torch.Tensor:
        """Latent points ``B x d`` for poses ``B x D`` (normalised features): each starts at the training latent
        point whose pose is nearest and minimises the observation GP's negative log-likelihood
        ``|W (y - mu_Y(x))|^2 / (2 s^2(x)) + D/2 ln s^2(x)`` by L-BFGS."""
        d2 = ((poses[:, None, :] - self.Y[None]) * self.W) .pow(2).sum(-1)
        x = self.X[d2.argmin(1)].clone().requires_grad_(True)
        opt = torch.optim.LBFGS([x], lr=1.0, max_iter=iterations, line_search_fn="strong_wolfe")
        D = poses.shape[1]

        def closure():
            opt.zero_grad()
            mean, var = self.predict_pose(x)
            s2 = var[:, 0] * self.W[0] ** 2  # the shared kernel variance
            nll = (((poses - mean) * self.W) ** 2).sum(-1) / (2 * s2) + 0.5 * D * torch.log(s2)
            nll.sum().backward()
            return nll.sum()

        opt.step(closure)
        return x.detach()

    def optimize_trajectory(self, history: torch.Tensor, initial: torch.Tensor, iterations: int = 100
                            ) -> torch.Tensor:
        """Refine a latent trajectory ``T x d`` following ``history`` (``order x d``, newest last) by maximising
        its dynamics likelihood with the learned points and hyperparameters fixed (Sec. 4.3), using the
        sequential conditionals ``N(x_t; mu_X(inputs_t), s_X^2(inputs_t) I)``; starts from ``initial``
        (e.g. the mean prediction)."""
        o, d = self.config.order, self.config.latent_dim
        traj = initial.clone().requires_grad_(True)
        opt = torch.optim.LBFGS([traj], lr=1.0, max_iter=iterations, line_search_fn="strong_wolfe")

        def closure():
            opt.zero_grad()
            full = torch.cat([history, traj])
            inputs = torch.stack([torch.cat([full[t - 1 - k] for k in range(o)]) for t in range(o, len(full))])
            mean, var = self.predict_latent(inputs)
            nll = ((full[o:] - mean) ** 2).sum(-1) / (2 * var) + 0.5 * d * torch.log(var)
            nll.sum().backward()
            return nll.sum()

        opt.step(closure)
        return traj.detach()

    def simulate(self, start: torch.Tensor, steps: int) -> torch.Tensor:
        """Mean-prediction trajectory ``steps x d`` from ``start`` (``order x d``, newest last)."""
        o = self.config.order
        hist = [start[i] for i in range(o)]
        out = []
        for _ in range(steps):
            inp = torch.cat([hist[-1 - k] for k in range(o)])[None]
            x, _ = self.predict_latent(inp)
            hist.append(x[0])
            out.append(x[0])
        return torch.stack(out)


def pca_init(Y: np.ndarray, d: int) -> np.ndarray:
    """The top ``d`` principal components of centred ``Y`` (``N x d``), scaled to unit variance per axis."""
    Yc = Y - Y.mean(0)
    U, S, _ = np.linalg.svd(Yc, full_matrices=False)
    X = U[:, :d] * S[:d]
    return X / X.std(0).clip(min=1e-12)


def train_gpdm(Y: np.ndarray, lengths: Sequence[int], config: GPDMConfig,
               progress: Callable[[int, float], None] | None = None) -> GPDM:
    """Learn a GPDM on observations ``Y`` (``N x D``, sequences concatenated) by L-BFGS."""
    t0 = time.perf_counter()
    model = GPDM(Y, lengths, config)  # PCA initialisation and L-BFGS: nothing random
    model.update_W()
    opt = torch.optim.LBFGS(model.parameters(), lr=1.0, max_iter=config.w_update_every,
                            line_search_fn="strong_wolfe", history_size=20)

    def closure():
        opt.zero_grad()
        value = model.objective()
        value.backward()
        return value

    done = 0
    while done < config.iterations:
        opt.step(closure)
        model.update_W()
        done += config.w_update_every
        with torch.no_grad():
            value = float(model.objective())
        if not math.isfinite(value):
            raise InputError("GPDM training diverged (the objective is not finite)")
        model.objective_history.append(value)
        if progress is not None:
            progress(min(done, config.iterations), value)
    model.training_seconds = time.perf_counter() - t0
    return model


# ---------------------------------------------------------------------------
# Model files
# ---------------------------------------------------------------------------

def save_gpdm(path: str | Path, model: GPDM, extra: dict | None = None) -> None:
    """Write a trained GPDM (latent points, data, scales, hyperparameters, config) and ``extra`` metadata
    (plain values or tensors) to a ``torch.save`` file loadable with ``weights_only=True``."""
    doc = {"format": FORMAT, "config": asdict(model.config), "lengths": list(model.lengths),
           "X": model.X.detach().clone(), "Y": model.Y.clone(), "W": model.W.clone(),
           "log_alpha": model.log_alpha.detach().clone(), "log_beta": model.log_beta.detach().clone(),
           "objective_history": [float(v) for v in model.objective_history], "extra": extra or {}}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    torch.save(doc, path)


def load_gpdm(path: str | Path) -> tuple[GPDM, dict]:
    """Read a model written by :func:`save_gpdm`: the GPDM and its ``extra`` metadata."""
    doc = read_model_file(path, FORMAT, "GPDM")
    config = dict(doc["config"])
    config.pop("seed", None)  # files written when the config carried an (unused) seed
    model = GPDM(doc["Y"].numpy(), doc["lengths"], GPDMConfig(**config), X=doc["X"].numpy())
    with torch.no_grad():
        model.log_alpha.copy_(doc["log_alpha"])
        model.log_beta.copy_(doc["log_beta"])
    model.W = doc["W"].clone()
    model.objective_history = list(doc["objective_history"])
    return model, dict(doc["extra"])


# ---------------------------------------------------------------------------
# As a motion prior: training on pose clips, model files with their data settings, the tracking prior
# ---------------------------------------------------------------------------

@dataclass
class GPDMPriorModel:
    """A GPDM trained on pose clips, with the normaliser and data settings it was trained with."""

    gpdm: GPDM
    normaliser: FeatureNormaliser
    fps: float
    body_model: str
    dof_names: list[str]
    sources: list[str]
    pose_step_rms: np.ndarray

    def save(self, path: str | Path) -> None:
        save_gpdm(path, self.gpdm, {
            "fps": float(self.fps), "body_model": self.body_model, "dof_names": list(self.dof_names),
            "sources": list(self.sources), "pose_step_rms": torch.tensor(self.pose_step_rms),
            "normaliser": normaliser_to_tensors(self.normaliser),
            "training_seconds": float(self.gpdm.training_seconds)})

    def summary(self) -> str:
        """One line on how training went."""
        h, c = self.gpdm.objective_history, self.gpdm.config
        fit = f"objective {h[0]:.1f} -> {h[-1]:.1f}, " if h else ""
        return (f"{c.latent_dim}D GPDM ({c.dynamics} dynamics, order {c.order}): {fit}"
                f"{self.gpdm.training_seconds:.1f} s")

    def check_compatible(self, body_model: str, dof_names: Sequence[str], fps: float | None,
                         source: str | Path | None = None) -> None:
        check_model_fits("GPDM", (self.body_model, self.dof_names, self.fps), body_model, dof_names, fps, source)


def train_gpdm_prior(clips: Sequence[np.ndarray], config: GPDMConfig, fps: float, dof_names: Sequence[str],
                     body_model: str = "15-cone", sources: Sequence[str] = (),
                     progress: Callable[[int, float], None] | None = None) -> GPDMPriorModel:
    """A GPDM on the invariant features of pose clips (each ``T x D`` at ``fps``), one sequence per clip."""
    normed, norm = clip_features(clips, dof_names)
    gpdm = train_gpdm(np.concatenate(normed), [len(f) for f in normed], config, progress)
    return GPDMPriorModel(gpdm, norm, fps, body_model, list(dof_names), list(sources), step_rms(clips))


def load_gpdm_prior(path: str | Path) -> GPDMPriorModel:
    gpdm, extra = load_gpdm(path)
    try:
        norm = normaliser_from_tensors(extra["normaliser"])
        model = GPDMPriorModel(gpdm, norm, float(extra["fps"]), extra["body_model"], list(extra["dof_names"]),
                               list(extra["sources"]), extra["pose_step_rms"].numpy())
    except (KeyError, AttributeError) as exc:
        raise InputError(f"GPDM file lacks the data settings of a motion prior ({exc})", path) from None
    gpdm.training_seconds = float(extra.get("training_seconds", 0.0))
    return model


class GPDMPrior(MotionPrior):
    """Samples every particle's next pose through the GPDM, in one batch.

    Each particle carries its latent history (``order`` points) and the pending root step of its newest
    frame (see :class:`priors.crbm.CRBMPrior` for why). A step draws the next latent point from the dynamics
    GP, mean plus ``noise_scale`` times the predictive standard deviation; the observation GP's mean gives
    the new frame's invariant features; the root moves by the pending step, plus ``root_noise_mm`` of
    ground-plane diffusion. Initial latent points are the projections of the known poses.
    """

    name = "gpdm"
    order = 1

    def __init__(self, model: GPDMPriorModel, noise_scale: float = 1.0, root_noise_mm: float = ROOT_NOISE_MM):
        if not noise_scale >= 0 or not root_noise_mm >= 0:
            raise InputError("GPDM noise scale and root noise must be non-negative")
        self.model = model
        self.predictor = model.gpdm.prepare()
        self.latent_order = model.gpdm.config.order
        self.noise_scale = float(noise_scale)
        self.root_noise_mm = float(root_noise_mm)

    def settings(self) -> dict:
        return {"latent_noise": self.noise_scale, "root_noise_mm": self.root_noise_mm}

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        known = np.atleast_2d(np.asarray(known, float))
        o = self.latent_order
        recent = known[-o:] if len(known) >= o else np.repeat(known[:1], o, axis=0)
        recent_feats = poses_to_invariant(np.concatenate([recent[:1], recent]))[1:]
        latent = self.predictor.project(torch.tensor(self.model.normaliser.transform(recent_feats)))
        history = torch.cat([latent[-1 - k] for k in range(o)]).numpy()  # newest first
        return {"latent": np.repeat(history[None], n_particles, axis=0),
                "step": np.repeat(pending_step(known)[None], n_particles, axis=0)}

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        step = list(STEP_FEATURES)
        inputs = torch.tensor(state["latent"])
        with torch.no_grad():
            mean, var = self.predictor.predict_latent(inputs)
            noise = torch.randn(mean.shape, generator=torch_generator(rng, "cpu"), dtype=torch.float64)
            x = mean + self.noise_scale * var.sqrt()[:, None] * noise
            pose_features, _ = self.predictor.predict_pose(x)
        f_next = self.model.normaliser.inverse(pose_features.numpy())
        previous = np.zeros_like(f_next)
        previous[:, step] = state["step"]
        poses = add_ground_diffusion(next_poses(history[:, -1], previous, f_next), self.root_noise_mm, rng)
        d = self.model.gpdm.config.latent_dim
        latent = np.concatenate([x.numpy(), state["latent"][:, :-d]], axis=1) if self.latent_order > 1 \
            else x.numpy()
        return poses, {"latent": latent, "step": f_next[:, step]}

    def diffusion_std(self) -> np.ndarray:
        return self.model.pose_step_rms


# ---------------------------------------------------------------------------
# Registration: building from a model file, training from clips
# ---------------------------------------------------------------------------

def train_gpdm_from_data(data: TrainingData, options: dict, rng: np.random.Generator,
                         progress: Callable[[int, int, dict], None] | None = None,
                         checkpoint: Path | None = None) -> GPDMPriorModel:
    """``train --prior gpdm``: a GPDM on the clips of ``data`` (deterministic: ``rng`` is not drawn from)."""
    config = GPDMConfig(latent_dim=options["latent_dim"], dynamics=options["dynamics"], order=options["order"],
                        balance=options["balance"], iterations=options["iterations"]).check()
    report = None if progress is None else (
        lambda done, value: progress(done, config.iterations, {"objective": value}))
    return train_gpdm_prior(list(data.clips), config, data.fps, data.body_model.dof_names, data.body_model.name,
                            list(data.sources), report)


GPDM_TRAIN_OPTIONS = (
    Option("latent_dim", int, GPDMConfig.latent_dim, "latent dimensions (default 3)", minimum=1),
    Option("dynamics", str, GPDMConfig.dynamics, "dynamics kernel (default linear+rbf)", choices=DYNAMICS),
    Option("order", int, GPDMConfig.order, "dynamics order 1 or 2 (default 1)", choices=(1, 2)),
    Option("balance", float, GPDMConfig.balance,
           "exponent M of the prior on the observation hyperparameters (default 1)", minimum=0.0, strict=True),
    Option("iterations", int, GPDMConfig.iterations, "L-BFGS iterations (default 300)", minimum=1),
)


@register_prior(
    "gpdm", summary="Gaussian Process Dynamical Model (Wang 2005), latent coordinates carried per particle",
    model_files="one", train=train_gpdm_from_data, train_options=GPDM_TRAIN_OPTIONS,
    options=(Option("latent_noise", float, 1.0,
                    "multiple of the predictive standard deviation added to each latent step (default 1)",
                    minimum=0.0),
             Option("root_noise", float, ROOT_NOISE_MM, "ground-plane diffusion of each sample in mm (default 5)",
                    minimum=0.0)))
def build_gpdm(context: PriorContext, model_files: Sequence[Path], options: dict) -> GPDMPrior:
    model = load_gpdm_prior(model_files[0])
    model.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps, model_files[0])
    return GPDMPrior(model, noise_scale=options["latent_noise"], root_noise_mm=options["root_noise"])
