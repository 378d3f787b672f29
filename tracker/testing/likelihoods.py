"""The likelihood contract (:class:`tracker.engine.likelihood.Likelihood`) as a base class of tests.

A subclass fills :meth:`LikelihoodContract.make_likelihood`, :meth:`LikelihoodContract.make_frame` and
:meth:`LikelihoodContract.make_poses`; every ``test_*`` method then checks, through the public interface
(``prepare(frame)`` once, then the prepared frame scores pose batches ``P x D`` to log-likelihoods ``(P,)``):

- shapes: one float per pose, for a batch, a batch of one and an empty batch;
- values: finite or ``-inf``, never NaN or ``+inf``; not all equal (the likelihood looks at the poses); a pose
  with a NaN is impossible (``-inf``) and leaves the other poses' numbers alone;
- a batch scores each pose as it would be scored alone, in any order;
- the same frame prepared twice, or a batch scored twice, gives the same numbers;
- refusals: poses of the wrong width or without the batch axis, and a frame with another number of views
  than the likelihood's cameras, raise a ``ValueError`` (an :class:`~tracker.core.errors.InputError` is one)
  before any scoring;
- where the likelihood has a second path (e.g. a compiled CPU loop and the array path a GPU runs,
  :meth:`LikelihoodContract.array_path`), both give the same numbers.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood


class LikelihoodContract:
    """Checks an image likelihood against the contract the particle filter relies on.

    Subclass it in a test module (as ``TestMyLikelihood(LikelihoodContract)``) and fill the three factories;
    override :meth:`array_path` where the likelihood scores by two paths.
    """

    #: Poses in each batch.
    particles: int = 16
    #: How far a pose's log-likelihood scored in a batch may be from the one scored alone.
    batch_tolerance: float = 1e-6
    #: How far the second path's log-likelihoods (:meth:`array_path`) may be from the first's.
    path_tolerance: float = 1e-4

    # --- what a subclass provides ---------------------------------------------------------------------

    def make_likelihood(self) -> Likelihood:
        """The likelihood to check, for the cameras of :meth:`make_frame`'s views."""
        raise NotImplementedError(f"{type(self).__name__} must implement make_likelihood() -> Likelihood")

    def make_frame(self) -> Frame:
        """One frame's observations in the likelihood's views."""
        raise NotImplementedError(f"{type(self).__name__} must implement make_frame() -> Frame")

    def make_poses(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` poses ``n x D`` to score, within the body model's limits: some near the person in the frame,
        some far from it, so that their scores differ."""
        raise NotImplementedError(f"{type(self).__name__} must implement make_poses(rng, n) -> n x D poses")

    def array_path(self, likelihood: Likelihood, prepared: FrameLikelihood, poses: np.ndarray) -> np.ndarray | None:
        """The log-likelihoods ``(P,)`` of ``poses`` by the likelihood's second path (e.g. its array path, the
        steps a GPU runs, computed here with numpy), or None (the default) for a likelihood with one path."""
        return None

    # --- the contract ---------------------------------------------------------------------------------

    def _scored(self, seed: int = 0) -> tuple[Likelihood, FrameLikelihood, np.ndarray, np.ndarray]:
        likelihood = self.make_likelihood()
        prepared = likelihood.prepare(self.make_frame())
        poses = np.asarray(self.make_poses(np.random.default_rng(seed), self.particles), float)
        assert poses.shape[0] == self.particles and poses.ndim == 2, \
            f"make_poses gave {poses.shape}, not {self.particles} x D"
        return likelihood, prepared, poses, np.asarray(prepared(poses))

    def test_scores_one_float_per_pose(self):
        _, prepared, poses, scores = self._scored()
        assert scores.shape == (len(poses),) and np.issubdtype(scores.dtype, np.floating), \
            f"{len(poses)} poses scored as {scores.shape} {scores.dtype}"
        assert np.asarray(prepared(poses[:1])).shape == (1,)
        assert np.asarray(prepared(poses[:0])).shape == (0,)

    def test_scores_are_finite_or_minus_infinity_and_tell_poses_apart(self):
        _, _, _, scores = self._scored()
        assert not np.any(np.isnan(scores)) and not np.any(scores == np.inf), scores
        finite = scores[np.isfinite(scores)]
        assert finite.size >= 2 and np.ptp(finite) > 0, f"the poses scored alike: {scores}"

    def test_a_pose_with_a_nan_is_impossible_and_leaves_the_others_alone(self):
        _, prepared, poses, scores = self._scored()
        broken = poses.copy()
        broken[1, -1] = np.nan
        again = np.asarray(prepared(broken))
        assert again[1] == -np.inf, f"a pose with a NaN scored {again[1]}"
        keep = np.arange(len(poses)) != 1
        np.testing.assert_allclose(again[keep], scores[keep], rtol=0, atol=self.batch_tolerance)

    def test_a_batch_scores_each_pose_as_it_would_alone(self):
        _, prepared, poses, scores = self._scored()
        P = len(poses)
        for i in (0, P // 2, P - 1):
            alone = np.asarray(prepared(poses[i:i + 1]))
            np.testing.assert_allclose(alone[0], scores[i], rtol=0, atol=self.batch_tolerance,
                                       err_msg=f"pose {i} scored otherwise alone than in the batch")
        order = np.random.default_rng(1).permutation(P)
        np.testing.assert_allclose(np.asarray(prepared(poses[order])), scores[order], rtol=0,
                                   atol=self.batch_tolerance, err_msg="a shuffled batch scored otherwise")

    def test_the_same_frame_and_poses_score_the_same(self):
        likelihood, prepared, poses, scores = self._scored()
        assert np.array_equal(np.asarray(prepared(poses)), scores), "a batch scored twice scored otherwise"
        again = likelihood.prepare(self.make_frame())
        assert np.array_equal(np.asarray(again(poses)), scores), "the frame prepared again scored otherwise"

    def test_poses_of_the_wrong_shape_are_refused(self):
        import pytest

        _, prepared, poses, _ = self._scored()
        D = poses.shape[1]
        for bad in (poses[:, :-1], np.concatenate([poses, poses[:, :1]], axis=1), poses[0]):
            with pytest.raises(ValueError, match=str(D)):
                prepared(bad)

    def test_a_frame_of_other_views_is_refused(self):
        import pytest

        likelihood = self.make_likelihood()
        frame = self.make_frame()
        n = frame.n_views
        for views in ([*range(n), 0], list(range(n - 1)) if n > 1 else None):
            if views is None:
                continue
            with pytest.raises(ValueError, match=f"{len(views)} views"):
                likelihood.prepare(_views(frame, views))

    def test_the_second_path_gives_the_same_numbers(self):
        likelihood, prepared, poses, scores = self._scored()
        other = self.array_path(likelihood, prepared, poses)
        if other is None:
            import pytest

            pytest.skip(f"{type(likelihood).__name__} scores by one path")
        np.testing.assert_allclose(np.asarray(other), scores, rtol=0, atol=self.path_tolerance)


def _views(frame: Frame, views: list[int]) -> Frame:
    """``frame`` with the images (and masks, background plates and keypoints, where it has them) of ``views``."""
    pick = (lambda items: None if items is None else tuple(items[v] for v in views))
    keypoints = None if frame.keypoints is None else frame.keypoints[views]
    return dataclasses.replace(frame, images=pick(frame.images), masks=pick(frame.masks),
                               backgrounds=pick(frame.backgrounds), keypoints=keypoints)
