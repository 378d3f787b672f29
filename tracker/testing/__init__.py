"""Contract tests for the toolkit's extension points, as base classes a plugin's own tests inherit.

A plugin's test module subclasses a contract (the class name starting with ``Test``, so that pytest collects
it), fills the factory methods, and pytest runs every ``test_*`` method of the contract against the plugin::

    from tracker.testing import PriorContract

    class TestDampedVelocity(PriorContract):
        def make_prior(self):
            return DampedVelocityPrior(np.full(40, 2.0), damping=0.8)

        def known_poses(self):
            return walking_poses()          # T x 40, a few frames of real motion

- :class:`PriorContract`: a :class:`~tracker.engine.prior.MotionPrior` samples a batch as it samples each
  particle alone, draws the same poses from the same seed, keeps state and histories together when the filter
  reindexes them, continues to the same poses from a checkpoint, starts with one state row per particle and
  grows its history from one known frame; each of its parts (:class:`priors.parts.Part`) is checked through the
  part protocol (its declared state, reindexed and checkpointed by rows, its summary, settings and noise);
- :class:`LikelihoodContract`: a :class:`~tracker.engine.likelihood.Likelihood` scores a batch as it scores each
  pose alone, gives one finite or ``-inf`` number per pose, refuses poses and frames of the wrong shape, and
  (where it has two paths, e.g. a compiled CPU loop and an array path for GPUs) gives the same numbers on both;
- :class:`MocapReaderContract`: a mocap reader (:mod:`data_tools.motion.readers`) is found by its suffix and reads its
  files as named points in millimetres, z up, at the file's frame rate, and refuses a bad file in one line.

The contracts need pytest only when their tests run; importing this package (or the toolkit) imports no test
framework. They live in the application layer's place: they may use the whole toolkit, and nothing in the
toolkit imports them.
"""
from tracker.testing.likelihoods import LikelihoodContract
from tracker.testing.mocap import MocapReaderContract
from tracker.testing.priors import PriorContract

__all__ = ["LikelihoodContract", "MocapReaderContract", "PriorContract"]
