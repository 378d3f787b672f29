"""Prediction with a trained GPDM (Wang 2005, eqs. 4.4-4.5): every factor computed once (:func:`prepare`), mean
and variance of the next latent point and of the pose, projection of poses into the latent space, and the
tracking prior's batched step (:class:`GPDMSampler`)."""
from __future__ import annotations

from dataclasses import dataclass, field

import torch

from priors.gpdm.model import GPDM, GPDMConfig, _cholesky, _Sparse


def prepare(model: GPDM) -> "GPDMPredictor":
    """The predictor of a trained ``model`` (its factors computed once, on first use)."""
    return GPDMPredictor.of(model)


@dataclass
class _Head:
    """One GP's predictions at new inputs ``x`` from precomputed factors: mean ``k(x, Z) @ w`` and variance
    ``k(x, x) + s2 - |k(x, Z) P_-^T|^2 + |k(x, Z) P_+^T|^2`` (``P_+`` only for a sparse GP).

    Exact (``Z`` all training inputs, ``L L^T = K + s2 I``): ``w = K^-1 T``, ``P_- = L^-1``. Sparse (``Z`` the
    inducing inputs; the predictive distribution of DTC, the same for VFE, and of FITC with its per-frame
    noise): ``w = L^-T L_B^-T c``, ``P_- = L^-1``, ``P_+ = L_B^-1 L^-1``, i.e. mean
    ``k_*u (K_uu + K_uf Lam^-1 K_fu)^-1 K_uf Lam^-1 T`` (see :class:`_Sparse`)."""

    Z: torch.Tensor
    w: torch.Tensor
    PT: torch.Tensor  # [P_-^T, P_+^T] side by side (n_Z x n_Z or n_Z x 2 n_Z)
    s2: torch.Tensor

    @classmethod
    def exact(cls, K: torch.Tensor, Z: torch.Tensor, T: torch.Tensor, s2: torch.Tensor, what: str) -> "_Head":
        L = _cholesky(K + s2 * torch.eye(len(K), dtype=K.dtype), what)
        Linv = torch.linalg.solve_triangular(L, torch.eye(len(K), dtype=K.dtype), upper=False)
        return cls(Z, torch.cholesky_solve(T, L), Linv.T.contiguous(), s2)

    @classmethod
    def sparse(cls, Kuu: torch.Tensor, Kuf: torch.Tensor, k_diag: torch.Tensor, Z: torch.Tensor, T: torch.Tensor,
               s2: torch.Tensor, what: str, method: str) -> "_Head":
        sp = _Sparse.of(Kuu, Kuf, k_diag, s2, what, method)
        eye = torch.eye(len(Kuu), dtype=Kuu.dtype)
        Linv = torch.linalg.solve_triangular(sp.L, eye, upper=False)
        P2 = torch.linalg.solve_triangular(sp.LB, Linv, upper=False)
        return cls(Z, P2.T @ sp.c(T), torch.cat([Linv.T, P2.T], dim=1).contiguous(), s2)

    def mean(self, k: torch.Tensor) -> torch.Tensor:
        return k @ self.w

    def var(self, k: torch.Tensor, k_diag: torch.Tensor, PT: torch.Tensor | None = None) -> torch.Tensor:
        """The variance; the product with ``P`` in ``PT``'s dtype when given (``PT``: this head's, cast)."""
        PT = self.PT if PT is None else PT
        v = (k.to(PT.dtype) @ PT) ** 2
        n = len(self.Z)
        var = k_diag + self.s2 - v[:, :n].sum(1).to(k_diag.dtype)
        if v.shape[1] > n:
            var = var + v[:, n:].sum(1).to(k_diag.dtype)
        return var.clamp_min(1e-12)


@dataclass
class GPDMPredictor:
    """Everything prediction needs, as plain tensors (no autograd), with the factors of both GPs computed once
    (:func:`prepare`); a sparse model predicts through its inducing points only."""

    config: GPDMConfig
    X: torch.Tensor
    Y: torch.Tensor
    W: torch.Tensor
    log_alpha: torch.Tensor
    log_beta: torch.Tensor
    in_idx: torch.Tensor
    out_idx: torch.Tensor
    active: torch.Tensor | None = None
    dyn_active: torch.Tensor | None = None
    _heads: dict = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, m: GPDM) -> "GPDMPredictor":
        p = cls(m.config, m.X.detach().clone(), m.Y.clone(), m.W.clone(), m.log_alpha.detach().clone(),
                m.log_beta.detach().clone(), m.in_idx.clone(), m.out_idx.clone(), m.active, m.dyn_active)
        p._factors()
        return p

    @property
    def sparse(self) -> bool:
        return self.active is not None

    def _model(self) -> GPDM:
        """A parameter shell for the kernels."""
        g = GPDM.__new__(GPDM)
        g.config, g.X, g.Y, g.W = self.config, self.X, self.Y, self.W
        g.log_alpha, g.log_beta = self.log_alpha, self.log_beta
        g.in_idx, g.out_idx, g.active, g.dyn_active = self.in_idx, self.out_idx, self.active, self.dyn_active
        return g

    def _factors(self) -> dict:
        """``g`` (kernel shell), ``latent`` and ``pose`` (:class:`_Head`), computed on first use."""
        if not self._heads:
            g = self._model()
            a, b = self.log_alpha.exp(), self.log_beta.exp()
            Xin, Xout = g.dynamics_inputs(), self.X[self.out_idx]
            if self.sparse:
                Zin, Xu = Xin[self.dyn_active], self.X[self.active]
                method = self.config.sparse_method
                latent = _Head.sparse(g._k_x(Zin, Zin), g._k_x(Zin, Xin), g._k_x_diag(Xin), Zin, Xout, 1 / a[-1],
                                      "dynamics", method)
                pose = _Head.sparse(g._k_y(Xu, Xu), g._k_y(Xu, self.X), b[0].expand(len(self.X)), Xu, self.Y,
                                    1 / b[2], "observation", method)
            else:
                latent = _Head.exact(g._k_x(Xin, Xin), Xin, Xout, 1 / a[-1], "dynamics")
                pose = _Head.exact(g._k_y(self.X, self.X), self.X, self.Y, 1 / b[2], "observation")
            self._heads.update(g=g, latent=latent, pose=pose)
        return self._heads

    def predict_latent(self, inputs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean ``B x d`` and variance ``(B,)`` of the next latent point for dynamics inputs ``B x (order d)``."""
        f = self._factors()
        h = f["latent"]
        k = f["g"]._k_x(inputs, h.Z)
        return h.mean(k), h.var(k, f["g"]._k_x_diag(inputs))

    def predict_pose(self, latent: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean ``B x D`` (normalised features) and per-dimension variance ``B x D`` of poses at latent points."""
        f = self._factors()
        h = f["pose"]
        k = f["g"]._k_y(latent, h.Z)
        var = h.var(k, self.log_beta.exp()[0].expand(len(latent)))
        return h.mean(k), var[:, None] / self.W[None, :] ** 2

    def sampler(self, dtype: torch.dtype = torch.float32) -> "GPDMSampler":
        """The batched step of the tracking prior, with the latent variance's ``B x n x n`` product in ``dtype``
        (see :class:`GPDMSampler`)."""
        f = self._factors()
        return GPDMSampler(f["g"], f["latent"], f["pose"], f["latent"].PT.to(dtype))

    def nearest_latent(self, poses: torch.Tensor) -> torch.Tensor:
        """Latent points ``B x d`` of the training frames whose poses are nearest to ``poses`` ``B x D``
        (normalised features, distances weighted by the observation GP's ``W``), by one matrix product."""
        a, b = poses.to(self.Y.dtype) * self.W, self.Y * self.W
        d2 = (a * a).sum(1, keepdim=True) - 2 * a @ b.T + (b * b).sum(1)[None]
        return self.X[d2.argmin(1)]

    def project(self, poses: torch.Tensor, iterations: int = 50) -> torch.Tensor:
        """Latent points ``B x d`` for poses ``B x D`` (normalised features): each starts at the training latent
        point whose pose is nearest and minimises the observation GP's negative log-likelihood
        ``|W (y - mu_Y(x))|^2 / (2 s^2(x)) + D/2 ln s^2(x)`` by L-BFGS."""
        x = self.nearest_latent(poses).clone().requires_grad_(True)
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


@dataclass
class GPDMSampler:
    """One step of the tracking prior for a batch of particles, no autograd: the next latent point drawn from
    the dynamics GP, and the observation GP's mean pose there.

    Kernels and means are float64: the weights ``K^-1 T`` are large (hundreds to thousands, of both signs), and
    a float32 kernel's rounding (5e-7) times them moved latent means by 5e-4 to 8e-4, 2-3% of the latent
    noise. The latent variance's product ``k P^T`` (``B x n x n``, the step's main cost) is in ``PT``'s dtype,
    float32 by default: its error was 3% of the variance at worst, 1.5% of the noise's standard deviation.
    """

    g: GPDM
    latent: _Head
    pose: _Head
    PT: torch.Tensor

    def step(self, inputs: torch.Tensor, noise: torch.Tensor, scale: float) -> tuple[torch.Tensor, torch.Tensor]:
        """Next latent points ``x = mu + scale sigma noise`` (``B x d``) for dynamics inputs ``B x (order d)`` and
        standard normal ``noise`` (``B x d``), and the mean normalised features ``B x D`` at ``x``."""
        inputs, noise = inputs.to(torch.float64), noise.to(torch.float64)
        with torch.no_grad():
            k = self.g._k_x(inputs, self.latent.Z)
            x = self.latent.mean(k)
            if scale > 0:
                x = x + scale * self.latent.var(k, self.g._k_x_diag(inputs), self.PT).sqrt()[:, None] * noise
            return x, self.pose.mean(self.g._k_y(x, self.pose.Z))
