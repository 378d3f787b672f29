"""Fitting the linear autoregressive model to pose clips by least squares."""
import numpy as np

from tracker.core.representation import clip_features, step_rms
from tracker.engine.registry import TrainingData

from .model import LinearARModel


def fit_linear_ar(data: TrainingData, ridge: float) -> LinearARModel:
    """``A`` and ``b`` minimising ``|x_t - A x_{t-1} - b|^2 + ridge |A|^2`` over every pair of consecutive frames
    of every clip (normalised invariant features); ``noise`` the residuals' standard deviation per feature."""
    features, normaliser = clip_features(data.clips, data.body_model.dof_names)  # one (T_i - 1) x K array per clip
    before = np.concatenate([f[:-1] for f in features])
    after = np.concatenate([f[1:] for f in features])
    X = np.hstack([before, np.ones((len(before), 1))])  # M x (K + 1): the last column fits b
    penalty = np.diag(np.r_[np.full(X.shape[1] - 1, ridge), 0.0])  # on A, not on b
    W = np.linalg.solve(X.T @ X + penalty, X.T @ after)  # (K + 1) x K
    return LinearARModel(A=W[:-1].T, b=W[-1], noise=(after - X @ W).std(axis=0), normaliser=normaliser,
                         fps=data.fps, body_model=data.body_model.name, dof_names=list(data.body_model.dof_names),
                         sources=list(data.sources), pose_step_rms=step_rms(data.clips))
